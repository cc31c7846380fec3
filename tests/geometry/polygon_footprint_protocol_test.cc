// The polygon footprint as the protocol carries it: the server accepts a convex outline in either winding (and
// stores it counter-clockwise), and refuses a bad one with an error naming the offending field.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "../service/test_robots.h"
#include "occgeo/geometry/convex_polygon.h"
#include "validation.h"

namespace occgeo::service {
namespace {

v1::Footprint polygon_message(const std::vector<std::pair<double, double>>& vertices, double height_m) {
  v1::Footprint footprint;
  footprint.mutable_polygon()->set_height_m(height_m);
  for (const auto& [x, y] : vertices) {
    auto* vertex = footprint.mutable_polygon()->add_vertices();
    vertex->set_x(x);
    vertex->set_y(y);
  }
  return footprint;
}

// The field an invalid footprint is refused for, or "" when it is accepted.
std::string refused_field(const v1::Footprint& footprint) {
  FieldError error;
  const auto parsed = footprint_from_proto(footprint, "collision.footprint", error);
  if (parsed) return "";
  EXPECT_FALSE(error.message.empty());
  return error.field;
}

TEST(PolygonFootprintMessage, AcceptsEitherWindingAndStoresItCounterClockwise) {
  const std::vector<std::pair<double, double>> counter_clockwise = {{0.4, -0.3}, {0.6, 0.0}, {0.4, 0.3}, {-0.3, 0.0}};
  const std::vector<std::pair<double, double>> clockwise(counter_clockwise.rbegin(), counter_clockwise.rend());
  for (const auto& vertices : {counter_clockwise, clockwise}) {
    FieldError error;
    const auto parsed = footprint_from_proto(polygon_message(vertices, 0.5), "robot_spec.footprint", error);
    ASSERT_TRUE(parsed) << error.field << ": " << error.message;
    const auto& polygon = std::get<geometry::ConvexPolygonFootprint>(*parsed);
    EXPECT_EQ(polygon.height, 0.5);
    ASSERT_EQ(polygon.vertices_B.size(), 4U);
    EXPECT_GT(geometry::twice_signed_area(polygon.vertices_B), 0.0);
    EXPECT_EQ(geometry::convex_polygon_problem(polygon.vertices_B, geometry::Orientation::counter_clockwise), "");
  }
}

TEST(PolygonFootprintMessage, EachErrorNamesTheOffendingField) {
  const std::vector<std::pair<double, double>> square = {{0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}, {-0.5, -0.5}};
  EXPECT_EQ(refused_field(polygon_message(square, 1.0)), "");
  EXPECT_EQ(refused_field(polygon_message(square, 0.0)), "collision.footprint.polygon.height_m");
  EXPECT_EQ(refused_field(polygon_message(square, NAN)), "collision.footprint.polygon.height_m");
  EXPECT_EQ(refused_field(polygon_message({{0, 0}, {1, 0}}, 1.0)), "collision.footprint.polygon.vertices");
  EXPECT_EQ(refused_field(polygon_message({{0, 0}, {1, 0}, {INFINITY, 1}}, 1.0)),
            "collision.footprint.polygon.vertices[2]");
  // A dent at vertex 3 (clockwise input: the client's own index is named).
  EXPECT_EQ(refused_field(polygon_message({{0, 1}, {1, 1}, {1, 0}, {0.5, 0.8}, {0, 0}}, 1.0)),
            "collision.footprint.polygon.vertices[3]");
  EXPECT_EQ(refused_field(polygon_message({{0, 0}, {1, 0}, {2, 0}, {1, 1}}, 1.0)),
            "collision.footprint.polygon.vertices[1]");
  EXPECT_EQ(refused_field(polygon_message({{0, 0}, {1, 1}, {2, 2}}, 1.0)), "collision.footprint.polygon.vertices");
  std::vector<std::pair<double, double>> many;
  for (int k = 0; k < 65; ++k) many.emplace_back(std::cos(2 * M_PI * k / 65), std::sin(2 * M_PI * k / 65));
  EXPECT_EQ(refused_field(polygon_message(many, 1.0)), "collision.footprint.polygon.vertices");
  many.pop_back();
  EXPECT_EQ(refused_field(polygon_message(many, 1.0)), "");
  EXPECT_EQ(refused_field(v1::Footprint{}), "collision.footprint");
}

TEST(PolygonFootprintMessage, ARobotSpecMayDeclareAPolygon) {
  v1::RobotSpec spec = testing::laser_probe_spec();
  *spec.mutable_footprint() = polygon_message({{0.5, 0.0}, {-0.25, 0.3}, {-0.25, -0.3}}, 0.4);
  FieldError error;
  const auto model = robot_model_from_spec("tri", spec, LimitsConfig{}, error);
  ASSERT_NE(model, nullptr) << error.field << ": " << error.message;
  EXPECT_TRUE(std::holds_alternative<geometry::ConvexPolygonFootprint>(model->footprint));
  EXPECT_NEAR(geometry::bounding_radius(model->footprint), 0.5, 1e-12);

  *spec.mutable_footprint() = polygon_message({{0.5, 0.0}, {-0.25, 0.3}, {0.1, 0.0}, {-0.25, -0.3}}, 0.4);
  EXPECT_EQ(robot_model_from_spec("tri", spec, LimitsConfig{}, error), nullptr);
  EXPECT_EQ(error.field, "robot_spec.footprint.polygon.vertices[2]");
}

}  // namespace
}  // namespace occgeo::service
