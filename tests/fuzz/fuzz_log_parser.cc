// Robot log parsers: lines of a CARMEN, DP-SLAM or URG log, either split in memory or read back from
// a file through LineSource (plain or gzipped). Whatever a line holds, a parser either skips it with
// a diagnostic or returns a scan the replay can send as is: finite pose and angles, a bounded beam
// count, and timestamps that the sanitizer turns into a finite, never decreasing sequence.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "occgeo/replay/diagnostics.h"
#include "occgeo/replay/line_source.h"
#include "occgeo/replay/parsers.h"

namespace {

using occgeo::fuzz::require;
using occgeo::replay::LogFormat;

constexpr std::size_t kMaxBeams = 100000;  // what the parsers accept at most (and the server's default limit)

struct Check {
  explicit Check(LogFormat format)
      : traits(occgeo::replay::traits_of(format)), sanitizer(traits.nominal_period_s, traits.wrap_period_s) {}

  void scan(const occgeo::replay::ScanRecord& record, occgeo::replay::Diagnostics& diagnostics) {
    require(std::isfinite(record.X_WB.x) && std::isfinite(record.X_WB.y) && std::isfinite(record.X_WB.theta),
            "a scan's pose is finite");
    require(std::isfinite(record.X_BS.x) && std::isfinite(record.X_BS.y) && std::isfinite(record.X_BS.theta),
            "a scan's laser mount is finite");
    require(std::isfinite(record.angle_min_rad) && std::isfinite(record.angle_increment_rad),
            "a scan's angles are finite");
    require(!record.ranges_m.empty() && record.ranges_m.size() <= kMaxBeams, "a scan has 1..100000 beams");
    for (const float range : record.ranges_m) require(!std::isnan(range), "no range is NaN");
    const double stamp = sanitizer.sanitize(record.stamp_s, diagnostics, record.line_number);
    require(std::isfinite(stamp), "a sanitized stamp is finite");
    require(!previous_stamp || stamp >= *previous_stamp, "sanitized stamps never decrease");
    previous_stamp = stamp;
  }

  occgeo::replay::FormatTraits traits;
  occgeo::replay::TimestampSanitizer sanitizer;
  std::optional<double> previous_stamp;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  // Byte 0: bits 0-1 the format (3 wraps to CARMEN), bit 2 read through a file instead of in memory.
  constexpr LogFormat kFormats[] = {LogFormat::carmen, LogFormat::dpslam, LogFormat::urg, LogFormat::carmen};
  const LogFormat format = kFormats[data[0] & 3U];
  const bool through_file = (data[0] & 4U) != 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);

  occgeo::replay::Diagnostics diagnostics;
  const auto parser = occgeo::replay::make_parser(format, diagnostics);
  Check check(format);
  if (through_file) {
    try {
      occgeo::replay::LineSource source(occgeo::fuzz::scratch().write("log", text));
      while (const auto line = source.next()) {
        if (const auto record = parser->parse_line(*line, source.line_number())) check.scan(*record, diagnostics);
        const double progress = source.progress();
        require(progress >= 0.0 && progress <= 1.0, "progress stays within 0..1");
      }
    } catch (const std::runtime_error&) {
      // A damaged gzip stream: the replay stops with this error naming the problem.
    }
  } else {
    std::size_t line_number = 0;
    std::size_t start = 0;
    while (start < text.size()) {
      std::size_t end = text.find('\n', start);
      if (end == std::string_view::npos) end = text.size();
      const auto record = parser->parse_line(text.substr(start, end - start), ++line_number);
      if (record) check.scan(*record, diagnostics);
      start = end + 1;
    }
  }
  return 0;
}
