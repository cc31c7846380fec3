#include "dynamic_family.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <vector>

namespace occgeo::testing {
namespace {

// Draws from the seed with its own arithmetic (std::uniform_*_distribution differ between standard libraries).
class Draw {
 public:
  explicit Draw(std::uint32_t seed) : engine_(seed * 2654435761U + 12345U) {}
  double uniform(double lo, double hi) {
    const double unit = static_cast<double>(engine_() >> 11) * 0x1.0p-53;
    return lo + (hi - lo) * unit;
  }
  int integer(int lo, int hi) {  // inclusive
    return lo + static_cast<int>(engine_() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  bool chance(double p) { return uniform(0.0, 1.0) < p; }

 private:
  std::mt19937_64 engine_;
};

std::string num(double v) {
  std::ostringstream out;
  out.precision(3);
  out << std::fixed << v;
  return out.str();
}

std::string point(const Eigen::Vector2d& p) { return "[" + num(p.x()) + ", " + num(p.y()) + "]"; }

struct Box {
  Eigen::Vector2d center;
  Eigen::Vector2d size;
};

struct Mover {
  std::string shape;  // YAML of the shape
  std::vector<Eigen::Vector2d> waypoints;
  double speed_mps = 0.0;
  bool loop = false;
  double start_s = 0.0;
  std::string what;
};

std::string person_shape() { return "{circle: {radius: 0.25, top_height: 1.7}}"; }
std::string cart_shape(bool along_x) {
  return along_x ? "{box: {size: [0.9, 0.6], top_height: 1.0}}" : "{box: {size: [0.6, 0.9], top_height: 1.0}}";
}

// Walls of a rectangle x in [x0, x1], y in [y0, y1] (inside), 0.2 m thick.
void add_enclosure(std::vector<Box>& boxes, double x0, double x1, double y0, double y1) {
  constexpr double t = 0.2;
  const double cx = (x0 + x1) / 2;
  const double cy = (y0 + y1) / 2;
  boxes.push_back({{cx, y1 + t / 2}, {x1 - x0 + 2 * t, t}});
  boxes.push_back({{cx, y0 - t / 2}, {x1 - x0 + 2 * t, t}});
  boxes.push_back({{x0 - t / 2, cy}, {t, y1 - y0}});
  boxes.push_back({{x1 + t / 2, cy}, {t, y1 - y0}});
}

// A person or cart crossing the robot's line y = 0 at x, between y_lo and y_hi: once or back and forth.
Mover crossing(Draw& draw, double x, double y_lo, double y_hi) {
  Mover m;
  const bool cart = draw.chance(0.25);
  m.shape = cart ? cart_shape(false) : person_shape();
  const bool from_right = draw.chance(0.5);
  const Eigen::Vector2d a(x, from_right ? y_lo : y_hi);
  const Eigen::Vector2d b(x, from_right ? y_hi : y_lo);
  m.waypoints = {a, b};
  m.speed_mps = cart ? draw.uniform(0.3, 0.45) : draw.uniform(0.3, 0.7);
  m.loop = draw.chance(0.5);
  m.start_s = draw.uniform(0.0, 20.0);
  m.what = std::string(cart ? "cart" : "person") + (m.loop ? " crossing back and forth" : " crossing once") + " at x " +
           num(x) + ", " + num(m.speed_mps) + " m/s from " + num(m.start_s) + " s";
  return m;
}

// Walking the robot's way, off its line by `offset`: along it (slower than the robot) or against it, ending at `stop`
// (it stands there afterwards) or looping back.
Mover lengthwise(Draw& draw, double x_near, double x_far, double offset) {
  Mover m;
  const bool cart = draw.chance(0.25);
  m.shape = cart ? cart_shape(true) : person_shape();
  const bool against = draw.chance(0.5);
  const Eigen::Vector2d near(x_near, offset);
  const Eigen::Vector2d far(x_far, offset);
  m.waypoints = against ? std::vector<Eigen::Vector2d>{far, near} : std::vector<Eigen::Vector2d>{near, far};
  m.speed_mps = cart ? draw.uniform(0.25, 0.4) : draw.uniform(0.25, 0.45);
  m.loop = draw.chance(0.4);
  m.start_s = draw.uniform(0.0, 10.0);
  m.what = std::string(cart ? "cart" : "person") + (against ? " walking against" : " walking along") +
           (m.loop ? " and back" : " then stopping") + " at y " + num(offset) + ", " + num(m.speed_mps) + " m/s from " +
           num(m.start_s) + " s";
  return m;
}

std::string world_yaml(const std::string& comment, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                       const std::vector<Box>& boxes, const std::vector<Eigen::Vector3d>& pillars,
                       const std::vector<Mover>& movers) {
  std::ostringstream out;
  out << "# " << comment << "\noccgeo_world: 1\nbounds: [" << point(lo) << ", " << point(hi) << "]\nshapes:\n";
  for (const Box& b : boxes) out << "  - box: {center: " << point(b.center) << ", size: " << point(b.size) << "}\n";
  for (const Eigen::Vector3d& p : pillars) {
    out << "  - circle: {center: " << point(p.head<2>()) << ", radius: " << num(p.z()) << "}\n";
  }
  if (movers.empty()) {
    out << "moving: []\n";
    return out.str();
  }
  out << "moving:\n";
  for (const Mover& m : movers) {
    out << "  - shape: " << m.shape << "\n    waypoints: [";
    for (std::size_t i = 0; i < m.waypoints.size(); ++i) out << (i ? ", " : "") << point(m.waypoints[i]);
    out << "]\n    speed: " << num(m.speed_mps) << "\n    loop: " << (m.loop ? "true" : "false")
        << "\n    start: " << num(m.start_s) << "\n";
  }
  return out.str();
}

}  // namespace

DynamicWorld make_dynamic_world(std::uint32_t seed) {
  Draw draw(seed);
  DynamicWorld world;
  std::vector<Box> boxes;
  std::vector<Eigen::Vector3d> pillars;  // x, y, radius
  std::vector<Mover> movers;
  const int kind = static_cast<int>(seed % 3);
  double length = 0.0;
  if (kind == 0) {
    // An aisle between shelves, with bays on both sides (recesses a cart can turn into).
    world.layout = "aisle";
    length = draw.uniform(12.0, 18.0);
    const double half = draw.uniform(1.3, 1.7);
    const double x0 = -1.5;
    const double x1 = length + 1.5;
    for (const double side : {1.0, -1.0}) {
      // Shelf segments along the aisle with 1-2 bays: gaps backed by a wall 1.5 m further out.
      std::vector<double> cuts = {x0};
      const int bays = draw.integer(1, 2);
      for (int i = 0; i < bays; ++i) {
        const double at = draw.uniform(2.0 + 5.0 * i, 5.0 + 5.0 * i);
        const double width = draw.uniform(1.2, 1.8);
        if (at + width >= x1 - 1.0) break;
        cuts.push_back(at);
        cuts.push_back(at + width);
      }
      cuts.push_back(x1);
      for (std::size_t i = 0; i + 1 < cuts.size(); i += 2) {
        boxes.push_back({{(cuts[i] + cuts[i + 1]) / 2, side * (half + 0.3)}, {cuts[i + 1] - cuts[i], 0.6}});
      }
      for (std::size_t i = 1; i + 1 < cuts.size(); i += 2) {
        const double a = cuts[i];
        const double b = cuts[i + 1];
        boxes.push_back({{(a + b) / 2, side * (half + 1.7)}, {b - a + 0.4, 0.2}});
      }
    }
    boxes.push_back({{x0 - 0.1, 0.0}, {0.2, 2 * half + 4.0}});
    boxes.push_back({{x1 + 0.1, 0.0}, {0.2, 2 * half + 4.0}});
    const int crossings = draw.integer(1, 2);
    for (int i = 0; i < crossings; ++i) {
      movers.push_back(crossing(draw, draw.uniform(3.0 + 5.0 * i, 6.0 + 5.0 * i), -half + 0.35, half - 0.35));
    }
    const double offset = (draw.chance(0.5) ? 1.0 : -1.0) * draw.uniform(0.55, half - 0.4);
    movers.push_back(lengthwise(draw, draw.uniform(2.5, 4.0), length - draw.uniform(1.5, 3.0), offset));
    const Eigen::Vector2d lo(x0 - 1.0, -half - 3.0);
    const Eigen::Vector2d hi(x1 + 1.0, half + 3.0);
    world.goal_W = {length, 0.0};
    world.yaml = world_yaml("generated aisle", lo, hi, boxes, pillars, movers);
    world.yaml_static = world_yaml("generated aisle, static", lo, hi, boxes, pillars, {});
  } else {
    // An open hall with pillars, or two rooms joined by a doorway.
    world.layout = kind == 1 ? "hall" : "doorway";
    length = draw.uniform(11.0, 15.0);
    const double half = draw.uniform(3.5, 5.0);
    add_enclosure(boxes, -2.0, length + 2.0, -half, half);
    double door_y = 0.0;
    if (kind == 2) {
      const double wall_x = length * draw.uniform(0.4, 0.6);
      const double door = draw.uniform(1.5, 2.0);
      door_y = draw.uniform(-1.2, 1.2);
      const double top_len = half - (door_y + door / 2);
      const double bottom_len = (door_y - door / 2) + half;
      boxes.push_back({{wall_x, door_y + door / 2 + top_len / 2}, {0.2, top_len}});
      boxes.push_back({{wall_x, door_y - door / 2 - bottom_len / 2}, {0.2, bottom_len}});
      // Someone coming through the door the other way, and someone crossing in front of it.
      Mover through;
      through.shape = draw.chance(0.3) ? cart_shape(true) : person_shape();
      through.waypoints = {{length - 1.0, door_y + draw.uniform(-0.5, 0.5)},
                           {wall_x + 1.2, door_y},
                           {wall_x - 1.2, door_y},
                           {draw.uniform(1.5, 3.0), (door_y > 0 ? -1.0 : 1.0) * 2.0}};
      through.speed_mps = draw.uniform(0.3, 0.5);
      through.start_s = draw.uniform(0.0, 20.0);
      through.what = "through the doorway against the robot, " + num(through.speed_mps) + " m/s from " +
                     num(through.start_s) + " s";
      movers.push_back(through);
      movers.push_back(crossing(draw, wall_x + draw.uniform(1.5, 2.5), -half + 0.5, half - 0.5));
    } else {
      const int count = draw.integer(3, 6);
      for (int i = 0, tries = 0; i < count && tries < 200; ++tries) {
        const Eigen::Vector3d p(draw.uniform(1.5, length - 1.5), draw.uniform(-half + 1.0, half - 1.0),
                                draw.uniform(0.2, 0.4));
        const bool clear_of_ends = p.head<2>().norm() > 1.5 && (p.head<2>() - Eigen::Vector2d(length, 0)).norm() > 1.5;
        const bool apart = std::all_of(pillars.begin(), pillars.end(), [&](const Eigen::Vector3d& q) {
          return (q.head<2>() - p.head<2>()).norm() > 2.0;
        });
        if (!clear_of_ends || !apart) continue;
        pillars.push_back(p);
        ++i;
      }
      const int crossings = draw.integer(1, 2);
      for (int i = 0; i < crossings; ++i) {
        movers.push_back(crossing(draw, draw.uniform(3.0 + 4.0 * i, 5.0 + 4.0 * i), -half + 0.5, half - 0.5));
      }
      movers.push_back(lengthwise(draw, draw.uniform(2.5, 4.0), length - draw.uniform(1.5, 3.0),
                                  (draw.chance(0.5) ? 1.0 : -1.0) * draw.uniform(0.6, 1.5)));
    }
    const Eigen::Vector2d lo(-3.0, -half - 1.0);
    const Eigen::Vector2d hi(length + 3.0, half + 1.0);
    world.goal_W = {length, 0.0};
    world.yaml = world_yaml("generated " + world.layout, lo, hi, boxes, pillars, movers);
    world.yaml_static = world_yaml("generated " + world.layout + ", static", lo, hi, boxes, pillars, {});
  }
  world.name = world.layout + "-" + std::to_string(seed);
  world.moving_obstacles = static_cast<int>(movers.size());
  for (const Mover& m : movers) world.description += (world.description.empty() ? "" : "; ") + m.what;
  return world;
}

}  // namespace occgeo::testing
