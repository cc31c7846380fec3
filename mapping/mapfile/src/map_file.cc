#include "occgeo/mapfile/map_file.h"

#include <yaml-cpp/yaml.h>

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>

namespace occgeo::mapfile {

namespace {

constexpr std::array<std::string_view, 7> kMapServerKeys = {"image",       "resolution", "origin", "occupied_thresh",
                                                            "free_thresh", "negate",     "mode"};

// Throws MapFileError for file.
[[noreturn]] void fail(const std::filesystem::path& file, const std::string& problem) {
  throw MapFileError(file.string() + ": " + problem);
}

// value in its shortest form that reads back exactly.
std::string format_number(double value) {
  std::array<char, 32> buffer{};
  const auto [end, error] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return error == std::errc{} ? std::string(buffer.data(), end) : std::string("?");
}

// Reads a whole file as bytes; throws MapFileError when it cannot be opened or read.
std::string read_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary | std::ios::ate);
  if (!in) fail(file, "cannot open file");
  const std::streamoff size = in.tellg();
  if (size < 0) fail(file, "cannot read file");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.seekg(0);
  if (!in.read(bytes.data(), size)) fail(file, "cannot read file");
  return bytes;
}

// Reader of the header tokens and pixel data of a PGM file (netpbm: whitespace-separated fields, '#' comments to the
// end of the line inside the header).
class PgmParser {
 public:
  PgmParser(const std::filesystem::path& file, std::string_view bytes) : file_(file), bytes_(bytes) {}

  OccupancyImage parse() {
    const std::string_view magic = bytes_.substr(0, 2);
    if (magic != "P5" && magic != "P2") fail(file_, "not a PGM image (expected magic P5 or P2)");
    position_ = 2;
    OccupancyImage image;
    image.width = static_cast<std::uint32_t>(read_header_number("width", std::numeric_limits<std::uint32_t>::max()));
    image.height = static_cast<std::uint32_t>(read_header_number("height", std::numeric_limits<std::uint32_t>::max()));
    const std::uint64_t max_value = read_header_number("maxval", std::numeric_limits<std::uint16_t>::max());
    if (max_value == 0 || max_value > 255) {
      fail(file_, "maxval " + std::to_string(max_value) + " is not supported (8-bit grey levels only)");
    }
    const std::uint64_t pixel_count = static_cast<std::uint64_t>(image.width) * image.height;
    if (magic == "P5") {
      ++position_;  // The single whitespace character after maxval.
      if (position_ > bytes_.size() || bytes_.size() - position_ < pixel_count) {
        fail(file_, "truncated: expected " + std::to_string(pixel_count) + " pixels");
      }
      const auto* first = reinterpret_cast<const std::uint8_t*>(bytes_.data() + position_);
      image.pixels.assign(first, first + pixel_count);
    } else {
      // Each plain pixel takes at least two bytes (a digit and a separator) except perhaps the last one.
      if ((bytes_.size() - position_) / 2 + 1 < pixel_count) {
        fail(file_, "truncated: expected " + std::to_string(pixel_count) + " pixels");
      }
      image.pixels.resize(pixel_count);
      for (auto& pixel : image.pixels) pixel = static_cast<std::uint8_t>(read_plain_pixel(max_value));
    }
    if (max_value != 255) {
      for (auto& pixel : image.pixels) pixel = static_cast<std::uint8_t>((pixel * 255U + max_value / 2) / max_value);
    }
    return image;
  }

 private:
  void skip_whitespace_and_comments() {
    while (position_ < bytes_.size()) {
      const char c = bytes_[position_];
      if (c == '#') {
        while (position_ < bytes_.size() && bytes_[position_] != '\n') ++position_;
      } else if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f') {
        ++position_;
      } else {
        return;
      }
    }
  }

  std::optional<std::uint64_t> read_number(std::uint64_t max) {
    skip_whitespace_and_comments();
    std::uint64_t value = 0;
    const char* first = bytes_.data() + position_;
    const auto [end, error] = std::from_chars(first, bytes_.data() + bytes_.size(), value);
    if (error != std::errc{} || value > max) return std::nullopt;
    position_ += static_cast<std::size_t>(end - first);
    return value;
  }

  std::uint64_t read_header_number(const std::string& field, std::uint64_t max) {
    const std::optional<std::uint64_t> value = read_number(max);
    if (!value) fail(file_, "bad PGM header field '" + field + "'");
    return *value;
  }

  std::uint64_t read_plain_pixel(std::uint64_t max_value) {
    const std::optional<std::uint64_t> value = read_number(max_value);
    if (!value) fail(file_, "bad or truncated plain PGM pixel data (values must be in [0, maxval])");
    return *value;
  }

  const std::filesystem::path& file_;
  std::string_view bytes_;
  std::size_t position_ = 0;
};

// Typed access to the keys of one map YAML document, with errors naming the file and the key.
class YamlKeys {
 public:
  YamlKeys(const std::filesystem::path& file, const YAML::Node& root) : file_(file), root_(root) {}

  [[nodiscard]] bool has(const std::string& key) const { return static_cast<bool>(root_[key]); }

  [[nodiscard]] YAML::Node required(const std::string& key) const {
    YAML::Node node = root_[key];
    if (!node) fail(file_, "missing key '" + key + "'");
    return node;
  }

  [[nodiscard]] std::string string(const std::string& key) const {
    const YAML::Node node = required(key);
    if (!node.IsScalar() || node.Scalar().empty()) fail(file_, "key '" + key + "': expected a non-empty string");
    return node.Scalar();
  }

  [[nodiscard]] double number(const std::string& key, const YAML::Node& node) const {
    double value = 0.0;
    if (!node.IsScalar() || !YAML::convert<double>::decode(node, value) || !std::isfinite(value)) {
      fail(file_, "key '" + key + "': expected a finite number");
    }
    return value;
  }

  [[nodiscard]] double number(const std::string& key) const { return number(key, required(key)); }

  [[nodiscard]] double probability(const std::string& key) const {
    const double value = number(key);
    if (value < 0.0 || value > 1.0) fail(file_, "key '" + key + "' must be in [0, 1], got " + format_number(value));
    return value;
  }

  // map_server writes negate as 0 or 1; YAML booleans are accepted too.
  [[nodiscard]] bool flag(const std::string& key) const {
    const YAML::Node node = required(key);
    int as_int = 0;
    bool as_bool = false;
    if (node.IsScalar() && YAML::convert<int>::decode(node, as_int) && (as_int == 0 || as_int == 1)) return as_int == 1;
    if (node.IsScalar() && YAML::convert<bool>::decode(node, as_bool)) return as_bool;
    fail(file_, "key '" + key + "': expected 0, 1, true or false");
  }

 private:
  const std::filesystem::path& file_;
  const YAML::Node& root_;
};

// The YAML document of yaml_file.
YAML::Node load_yaml(const std::filesystem::path& yaml_file) {
  const std::string text = read_file(yaml_file);
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    fail(yaml_file, std::string("invalid YAML: ") + e.what());
  }
}

// Throws MapFileError for the first key of root that map_server does not define.
void check_keys_are_known(const std::filesystem::path& yaml_file, const YAML::Node& root) {
  for (const auto& entry : root) {
    const std::string key = entry.first.Scalar();
    bool known = false;
    for (const std::string_view known_key : kMapServerKeys) known = known || key == known_key;
    if (!known) {
      fail(yaml_file, "unknown key '" + key +
                          "' (map_server keys: image, resolution, origin, occupied_thresh, free_thresh, negate, mode)");
    }
  }
}

// YAML double-quoted form of s.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      constexpr std::string_view kHex = "0123456789abcdef";
      out += "\\x";
      out += kHex[static_cast<unsigned char>(c) >> 4];
      out += kHex[static_cast<unsigned char>(c) & 0xF];
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// Throws MapFileError when image cannot be written as a map (pixel count, resolution, origin, thresholds).
void check_writable(const std::filesystem::path& prefix, const OccupancyImage& image) {
  if (image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    fail(prefix, "image has " + std::to_string(image.pixels.size()) + " pixels, width * height is " +
                     std::to_string(static_cast<std::uint64_t>(image.width) * image.height));
  }
  if (!std::isfinite(image.resolution) || image.resolution <= 0.0) {
    fail(prefix, "resolution must be a finite number > 0, got " + format_number(image.resolution));
  }
  if (!std::isfinite(image.origin_x) || !std::isfinite(image.origin_y)) fail(prefix, "origin must be finite");
  if (image.origin_yaw != 0.0) {
    fail(prefix, "origin yaw " + format_number(image.origin_yaw) + " is not supported (only 0)");
  }
  for (const auto& [key, value] :
       {std::pair{"occupied_thresh", image.occupied_thresh}, std::pair{"free_thresh", image.free_thresh}}) {
    if (!(value >= 0.0 && value <= 1.0)) {
      fail(prefix, std::string(key) + " must be in [0, 1], got " + format_number(value));
    }
  }
}

// Writes bytes to file, replacing it; throws MapFileError when that fails.
void write_file(const std::filesystem::path& file, std::string_view bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) fail(file, "cannot write file");
}

}  // namespace

OccupancyImage::CellState OccupancyImage::state(std::uint32_t col, std::uint32_t row) const {
  const double grey = pixel(col, row);
  const double p = negate ? grey / 255.0 : (255.0 - grey) / 255.0;
  if (p > occupied_thresh) return CellState::occupied;
  if (p < free_thresh) return CellState::free;
  return CellState::unknown;
}

MapPoint OccupancyImage::pixel_center(std::uint32_t col, std::uint32_t row) const {
  return {origin_x + (col + 0.5) * resolution, origin_y + (static_cast<double>(height) - 1.0 - row + 0.5) * resolution};
}

OccupancyImage read_map_yaml(const std::filesystem::path& yaml_file) {
  const YAML::Node root = load_yaml(yaml_file);
  if (!root.IsMap()) fail(yaml_file, "expected a map of map_server keys");
  check_keys_are_known(yaml_file, root);
  const YamlKeys keys(yaml_file, root);

  const std::filesystem::path image_name = keys.string("image");
  const double resolution = keys.number("resolution");
  if (resolution <= 0.0) fail(yaml_file, "key 'resolution' must be > 0, got " + format_number(resolution));
  const YAML::Node origin = keys.required("origin");
  if (!origin.IsSequence() || origin.size() != 3) fail(yaml_file, "key 'origin': expected [x, y, yaw]");
  const double origin_yaw = keys.number("origin", origin[2]);
  if (origin_yaw != 0.0) {
    fail(yaml_file, "key 'origin': yaw " + format_number(origin_yaw) + " is not supported (only 0)");
  }
  if (keys.has("mode")) {
    const std::string mode = keys.string("mode");
    if (mode != "trinary" && mode != "scale") {
      fail(yaml_file, "key 'mode': '" + mode + "' is not supported (trinary or scale)");
    }
  }

  const std::filesystem::path image_file = image_name.is_absolute() ? image_name : yaml_file.parent_path() / image_name;
  OccupancyImage image = PgmParser(image_file, read_file(image_file)).parse();
  image.resolution = resolution;
  image.origin_x = keys.number("origin", origin[0]);
  image.origin_y = keys.number("origin", origin[1]);
  image.origin_yaw = origin_yaw;
  if (keys.has("occupied_thresh")) image.occupied_thresh = keys.probability("occupied_thresh");
  if (keys.has("free_thresh")) image.free_thresh = keys.probability("free_thresh");
  if (image.free_thresh > image.occupied_thresh) {
    fail(yaml_file, "key 'free_thresh' " + format_number(image.free_thresh) + " is above occupied_thresh " +
                        format_number(image.occupied_thresh));
  }
  if (keys.has("negate")) image.negate = keys.flag("negate");
  return image;
}

void write_map(const std::filesystem::path& prefix, const OccupancyImage& image) {
  check_writable(prefix, image);
  const std::filesystem::path pgm_file = prefix.string() + ".pgm";
  const std::filesystem::path yaml_file = prefix.string() + ".yaml";

  std::string pgm = "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n255\n";
  pgm.append(reinterpret_cast<const char*>(image.pixels.data()), image.pixels.size());
  write_file(pgm_file, pgm);

  std::ostringstream yaml;
  yaml << "image: " << quoted(pgm_file.filename().string()) << "\n"
       << "mode: trinary\n"
       << "resolution: " << format_number(image.resolution) << "\n"
       << "origin: [" << format_number(image.origin_x) << ", " << format_number(image.origin_y) << ", 0]\n"
       << "negate: " << (image.negate ? 1 : 0) << "\n"
       << "occupied_thresh: " << format_number(image.occupied_thresh) << "\n"
       << "free_thresh: " << format_number(image.free_thresh) << "\n";
  write_file(yaml_file, yaml.str());
}

}  // namespace occgeo::mapfile
