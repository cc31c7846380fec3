// Log parsers of `occgeo replay`: real excerpts of each dataset and every data quirk.
#include <gtest/gtest.h>
#include <algorithm>

#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "occgeo/replay/parsers.h"
#include "replay_excerpts.h"

namespace occgeo::replay {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<ScanRecord> parse_all(LogFormat format, const std::string& text, Diagnostics& diagnostics) {
  auto parser = make_parser(format, diagnostics);
  std::vector<ScanRecord> scans;
  const auto lines = lines_of(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (auto scan = parser->parse_line(lines[i], i + 1)) scans.push_back(std::move(*scan));
  }
  return scans;
}

// The n-th whitespace-separated field of a line replaced by `value`.
std::string with_field(const std::string& line, std::size_t n, const std::string& value) {
  std::istringstream in(line);
  std::vector<std::string> fields;
  for (std::string f; in >> f;) fields.push_back(f);
  fields.at(n) = value;
  std::string out;
  for (const auto& f : fields) out += (out.empty() ? "" : " ") + f;
  return out;
}

std::string first_fields(const std::string& line, std::size_t count) {
  std::istringstream in(line);
  std::string out;
  std::string f;
  for (std::size_t i = 0; i < count && in >> f; ++i) out += (out.empty() ? "" : " ") + f;
  return out;
}

std::string line_starting(const std::string& text, const std::string& prefix, int occurrence = 0) {
  for (const auto& line : lines_of(text)) {
    if (line.rfind(prefix, 0) == 0 && occurrence-- == 0) return line;
  }
  return {};
}

// ---- CARMEN ----------------------------------------------------------------------------------------------------

TEST(CarmenParser, RealIntelExcerptGivesTwoScansWithTheirCorrectedPoses) {
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::carmen, testing::kCarmenIntelExcerpt, diagnostics);
  ASSERT_EQ(scans.size(), 2U);
  EXPECT_EQ(diagnostics.warnings(), 0U);
  for (const auto& scan : scans) {
    ASSERT_EQ(scan.ranges_m.size(), 180U);
    EXPECT_DOUBLE_EQ(scan.angle_min_rad, -90.0 * kDeg);
    EXPECT_DOUBLE_EQ(scan.angle_increment_rad, 1.0 * kDeg);
    EXPECT_DOUBLE_EQ(scan.X_BS.x, 0.0);  // PARAM robot_frontlaser_offset 0.0
  }
  EXPECT_FLOAT_EQ(scans[0].ranges_m[0], 1.09F);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.x, 0.600266);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.y, -0.0320327);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.theta, -0.354665);
  EXPECT_DOUBLE_EQ(*scans[0].stamp_s, 32.9068);
  EXPECT_FLOAT_EQ(scans[1].ranges_m[0], 1.72F);
  EXPECT_DOUBLE_EQ(scans[1].X_WB.x, 0.68231);
  EXPECT_DOUBLE_EQ(scans[1].X_WB.theta, -0.938803);
  EXPECT_DOUBLE_EQ(*scans[1].stamp_s, 35.1051);
  // 81.83 is the no-return value in this log: 15 beams in the first scan, 14 in the second.
  EXPECT_EQ(diagnostics.no_return_beams(), 29U);
  EXPECT_TRUE(std::isinf(scans[0].ranges_m[110]));
  const auto& ignored = diagnostics.ignored_lines();
  EXPECT_EQ(ignored.at("comment"), 2U);
  EXPECT_EQ(ignored.at("PARAM"), 2U);
  EXPECT_EQ(ignored.at("ODOM"), 3U);
  EXPECT_EQ(ignored.at("NEFF"), 1U);
}

TEST(CarmenParser, TruncatedFlaserIsSkippedWithAWarning) {
  const std::string flaser = line_starting(testing::kCarmenIntelExcerpt, "FLASER");
  Diagnostics diagnostics;
  // Cut inside the ranges, and cut just before the ipc timestamp.
  const auto scans =
      parse_all(LogFormat::carmen, first_fields(flaser, 50) + "\n" + first_fields(flaser, 188) + "\n", diagnostics);
  EXPECT_TRUE(scans.empty());
  EXPECT_EQ(diagnostics.count("truncated_line"), 2U);
}

TEST(CarmenParser, FlaserWithoutHostAndLoggerStampIsStillUsable) {
  const std::string flaser = line_starting(testing::kCarmenIntelExcerpt, "FLASER");
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::carmen, first_fields(flaser, 189), diagnostics);
  ASSERT_EQ(scans.size(), 1U);
  EXPECT_DOUBLE_EQ(*scans[0].stamp_s, 32.9068);
}

TEST(CarmenParser, NonNumericFieldSkipsTheLine) {
  const std::string flaser = line_starting(testing::kCarmenIntelExcerpt, "FLASER");
  for (const std::size_t field : {std::size_t{1}, std::size_t{40}, std::size_t{183}, std::size_t{188}}) {
    Diagnostics diagnostics;
    const auto scans = parse_all(LogFormat::carmen, with_field(flaser, field, "1.0x"), diagnostics);
    EXPECT_TRUE(scans.empty()) << "field " << field;
    EXPECT_EQ(diagnostics.warnings(), 1U) << "field " << field;
  }
  Diagnostics diagnostics;
  EXPECT_TRUE(parse_all(LogFormat::carmen, with_field(flaser, 40, "nan"), diagnostics).empty());
  EXPECT_EQ(diagnostics.count("non_numeric_field"), 1U);
}

TEST(CarmenParser, NegativeRangeBecomesZeroWithAWarning) {
  const std::string flaser = line_starting(testing::kCarmenIntelExcerpt, "FLASER");
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::carmen, with_field(flaser, 2, "-1.5"), diagnostics);
  ASSERT_EQ(scans.size(), 1U);
  EXPECT_EQ(scans[0].ranges_m[0], 0.0F);
  EXPECT_EQ(diagnostics.count("negative_range"), 1U);
}

TEST(CarmenParser, UnknownLineTypesAreCountedAndWarnedKnownOnesOnlyCounted) {
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::carmen, "RLASER 1 2 3\nTRUEPOS 1 2 3\nBOGUS 1 2\n\n", diagnostics);
  EXPECT_TRUE(scans.empty());
  EXPECT_EQ(diagnostics.ignored_lines().at("RLASER"), 1U);
  EXPECT_EQ(diagnostics.ignored_lines().at("BOGUS"), 1U);
  EXPECT_EQ(diagnostics.ignored_lines().at("empty"), 1U);
  EXPECT_EQ(diagnostics.count("unknown_line_type"), 1U);
  EXPECT_EQ(diagnostics.warnings(), 1U);
}

TEST(CarmenParser, FrontLaserOffsetPlacesBaseLinkBehindTheFlaserPose) {
  Diagnostics diagnostics;
  std::string log = "PARAM robot_frontlaser_offset 0.25 nohost 0\nFLASER 3 1 2 81.91 1.0 2.0 1.5707963267948966";
  log += " 1.0 2.0 1.5707963267948966 10.5 host 10.5\n";
  const auto scans = parse_all(LogFormat::carmen, log, diagnostics);
  ASSERT_EQ(scans.size(), 1U);
  EXPECT_NEAR(scans[0].X_WB.x, 1.0, 1e-12);
  EXPECT_NEAR(scans[0].X_WB.y, 1.75, 1e-12);  // 0.25 m behind a laser facing +y
  EXPECT_DOUBLE_EQ(scans[0].X_BS.x, 0.25);
  EXPECT_DOUBLE_EQ(scans[0].angle_increment_rad, std::numbers::pi / 2.0);  // 3 beams over 180 deg
  EXPECT_TRUE(std::isinf(scans[0].ranges_m[2]));                           // 81.91 sentinel
}

TEST(CarmenParser, RobotLaser1UsesItsOwnGeometryRobotPoseAndLaserMount) {
  // laser_type start fov res max_range accuracy remission_mode n r1..r5 m rem1 rem2 laser(x y th) robot(x y th)
  // tv rv forward_safety side_safety turn_axis timestamp host logger_timestamp
  const std::string line =
      "ROBOTLASER1 0 -1.5707963 3.1415926 0.7853981 50.0 0.01 0 5 1.0 2.0 50.0 -3.0 4.0 2 7 8 "
      "2.1 3.0 0.0 2.0 3.0 0.0 0.1 0.0 0.5 0.3 1e6 42.25 host 42.25";
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::carmen, line, diagnostics);
  ASSERT_EQ(scans.size(), 1U);
  const auto& scan = scans[0];
  ASSERT_EQ(scan.ranges_m.size(), 5U);
  EXPECT_DOUBLE_EQ(scan.angle_min_rad, -1.5707963);
  EXPECT_DOUBLE_EQ(scan.angle_increment_rad, 0.7853981);
  EXPECT_TRUE(std::isinf(scan.ranges_m[2]));  // at max_range: no return
  EXPECT_EQ(scan.ranges_m[3], 0.0F);          // negative
  EXPECT_EQ(diagnostics.count("negative_range"), 1U);
  EXPECT_DOUBLE_EQ(scan.X_WB.x, 2.0);
  EXPECT_NEAR(scan.X_BS.x, 0.1, 1e-12);
  EXPECT_NEAR(scan.X_BS.y, 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(*scan.stamp_s, 42.25);

  Diagnostics cut;
  EXPECT_TRUE(parse_all(LogFormat::carmen, first_fields(line, 20), cut).empty());
  EXPECT_EQ(cut.count("truncated_line"), 1U);
}

// ---- DP-SLAM ---------------------------------------------------------------------------------------------------

TEST(DpSlamParser, RealLoop5ExcerptPairsOdometryWithLaser) {
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::dpslam, testing::kDpslamLoop5Excerpt, diagnostics);
  ASSERT_EQ(scans.size(), 2U);
  EXPECT_EQ(diagnostics.warnings(), 0U);
  EXPECT_FALSE(scans[0].stamp_s.has_value());
  ASSERT_EQ(scans[0].ranges_m.size(), 181U);
  EXPECT_DOUBLE_EQ(scans[0].angle_min_rad, -90.0 * kDeg);
  EXPECT_DOUBLE_EQ(scans[0].angle_increment_rad, 1.0 * kDeg);
  EXPECT_FLOAT_EQ(scans[0].ranges_m[0], 0.642F);
  EXPECT_FLOAT_EQ(scans[0].ranges_m[180], 1.264F);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.x, -2.424026);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.y, 4.800517);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.theta, 2.590948);
  EXPECT_DOUBLE_EQ(scans[1].X_WB.x, -2.424134);
  EXPECT_DOUBLE_EQ(scans[0].X_BS.x, 0.0);
}

TEST(DpSlamParser, SentinelValuesAreNoReturn) {
  const std::string laser = line_starting(testing::kDpslamLoop5Excerpt, "Laser");
  std::string edited = with_field(with_field(with_field(laser, 2, "8.191000"), 3, "8.183001"), 4, "7.990000");
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::dpslam, "Odometry 0 0 0\n" + edited, diagnostics);
  ASSERT_EQ(scans.size(), 1U);
  EXPECT_TRUE(std::isinf(scans[0].ranges_m[0]));
  EXPECT_TRUE(std::isinf(scans[0].ranges_m[1]));
  EXPECT_FLOAT_EQ(scans[0].ranges_m[2], 7.99F);
}

TEST(DpSlamParser, LaserWithoutOdometryTruncatedOrNonNumericIsSkipped) {
  const std::string laser = line_starting(testing::kDpslamLoop5Excerpt, "Laser");
  Diagnostics diagnostics;
  const std::string log = laser + "\n" +                                             // no odometry before it
                          "Odometry 1 2\n" +                                         // cut short
                          "Odometry 1 2 0.5\n" + first_fields(laser, 100) + "\n" +   // laser cut short
                          "Odometry 1 2 0.5\n" + with_field(laser, 7, "x") + "\n" +  // non-numeric range
                          "Odometry 1 2 0.5\nOdometry 1 2 0.6\n" + laser + "\n" +    // two odometries in a row
                          "Comment here\n";
  const auto scans = parse_all(LogFormat::dpslam, log, diagnostics);
  ASSERT_EQ(scans.size(), 1U);
  EXPECT_DOUBLE_EQ(scans[0].X_WB.theta, 0.6);
  EXPECT_EQ(diagnostics.count("laser_without_odometry"), 1U);
  EXPECT_EQ(diagnostics.count("truncated_line"), 2U);
  EXPECT_EQ(diagnostics.count("non_numeric_field"), 1U);
  EXPECT_EQ(diagnostics.count("odometry_without_laser"), 1U);
  EXPECT_EQ(diagnostics.count("unknown_line_type"), 1U);
}

// ---- URG / CoreSLAM --------------------------------------------------------------------------------------------

TEST(UrgParser, RealExp1ExcerptGivesMicrosecondStampsAndMillimetreRanges) {
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::urg, testing::kUrg04LxMinesExcerpt, diagnostics);
  ASSERT_EQ(scans.size(), 2U);
  EXPECT_EQ(diagnostics.warnings(), 0U);
  ASSERT_EQ(scans[0].ranges_m.size(), 682U);
  EXPECT_DOUBLE_EQ(*scans[0].stamp_s, 212.387282);
  EXPECT_DOUBLE_EQ(*scans[1].stamp_s, 212.484734);
  EXPECT_DOUBLE_EQ(scans[0].angle_min_rad, -120.0 * kDeg);
  EXPECT_NEAR(scans[0].angle_min_rad + 681.0 * scans[0].angle_increment_rad, 120.0 * kDeg, 1e-12);
  EXPECT_DOUBLE_EQ(scans[0].X_BS.x, 0.145);
  // 0 mm is one of the URG's error codes, not "no return": it is sent below range_min so the server skips it.
  EXPECT_EQ(scans[0].ranges_m[0], 0.0);
  EXPECT_FLOAT_EQ(scans[0].ranges_m[174], 2.229F);
  std::uint64_t error_codes = 0;
  for (const auto& scan : scans)
    error_codes += static_cast<std::uint64_t>(
        std::count_if(scan.ranges_m.begin(), scan.ranges_m.end(), [](double r) { return r < 0.02; }));
  EXPECT_GT(error_codes, 0U);
  EXPECT_EQ(diagnostics.invalid_beams(), error_codes);
  EXPECT_EQ(diagnostics.no_return_beams(), 0U);
  // Same tick counts in both lines: the robot has not moved.
  EXPECT_DOUBLE_EQ(scans[1].X_WB.x, 0.0);
  EXPECT_DOUBLE_EQ(scans[1].X_WB.theta, 0.0);
}

TEST(UrgParser, EqualTickIncrementsDriveStraight) {
  const std::string first = lines_of(testing::kUrg04LxMinesExcerpt)[0];
  const std::string moved = with_field(with_field(first, 2, "31221"), 3, "27178");  // +2000 ticks on both wheels
  Diagnostics diagnostics;
  const auto scans = parse_all(LogFormat::urg, first + "\n" + moved + "\n", diagnostics);
  ASSERT_EQ(scans.size(), 2U);
  // One wheel revolution: 2 pi 0.077 m.
  EXPECT_NEAR(scans[1].X_WB.x, 2.0 * std::numbers::pi * 0.077, 1e-12);
  EXPECT_NEAR(scans[1].X_WB.y, 0.0, 1e-12);
  EXPECT_NEAR(scans[1].X_WB.theta, 0.0, 1e-12);
}

TEST(UrgParser, TruncatedOrNonNumericLinesAreSkipped) {
  const std::string first = lines_of(testing::kUrg04LxMinesExcerpt)[0];
  Diagnostics diagnostics;
  const std::string log =
      first_fields(first, 400) + "\n" + with_field(first, 300, "12a") + "\n" + with_field(first, 0, "abc") + "\n";
  EXPECT_TRUE(parse_all(LogFormat::urg, log, diagnostics).empty());
  EXPECT_EQ(diagnostics.count("truncated_line"), 1U);
  EXPECT_EQ(diagnostics.count("non_numeric_field"), 2U);
}

// ---- timestamps --------------------------------------------------------------------------------------------------

TEST(TimestampSanitizer, IncreasingStampsPassThrough) {
  Diagnostics diagnostics;
  TimestampSanitizer stamps(0.2, 0.0);
  EXPECT_DOUBLE_EQ(stamps.sanitize(32.9068, diagnostics, 1), 32.9068);
  EXPECT_DOUBLE_EQ(stamps.sanitize(35.1051, diagnostics, 2), 35.1051);
  EXPECT_EQ(diagnostics.warnings(), 0U);
}

TEST(TimestampSanitizer, MissingStampsAreSynthesizedAtTheNominalPeriod) {
  Diagnostics diagnostics;
  TimestampSanitizer stamps(0.2, 0.0);
  EXPECT_DOUBLE_EQ(stamps.sanitize(std::nullopt, diagnostics, 1), 0.2);
  EXPECT_DOUBLE_EQ(stamps.sanitize(std::nullopt, diagnostics, 2), 0.4);
  EXPECT_EQ(diagnostics.warnings(), 0U);  // DP-SLAM has none by design: not a quirk
}

TEST(TimestampSanitizer, ZeroAndNegativeStampsFollowThePreviousOne) {
  Diagnostics diagnostics;
  TimestampSanitizer stamps(0.1, 0.0);
  EXPECT_DOUBLE_EQ(stamps.sanitize(0.0, diagnostics, 1), 0.1);
  EXPECT_DOUBLE_EQ(stamps.sanitize(5.0, diagnostics, 2), 5.0);
  EXPECT_DOUBLE_EQ(stamps.sanitize(-3.0, diagnostics, 3), 5.1);
  EXPECT_DOUBLE_EQ(stamps.sanitize(5.3, diagnostics, 4), 5.3);
  EXPECT_EQ(diagnostics.count("timestamp_not_positive"), 2U);
}

TEST(TimestampSanitizer, NonIncreasingStampsAreNudgedForward) {
  // As in intel-corrected.log.gz line 5647: 940.54 after 940.654.
  Diagnostics diagnostics;
  TimestampSanitizer stamps(0.2, 0.0);
  stamps.sanitize(940.654, diagnostics, 1);
  EXPECT_NEAR(stamps.sanitize(940.54, diagnostics, 2), 940.655, 1e-9);
  EXPECT_NEAR(stamps.sanitize(940.655, diagnostics, 3), 940.656, 1e-9);  // equal is not increasing either
  EXPECT_DOUBLE_EQ(stamps.sanitize(941.0, diagnostics, 4), 941.0);
  EXPECT_EQ(diagnostics.count("timestamp_not_increasing"), 2U);
}

TEST(TimestampSanitizer, WrappingCounterIsUnwrapped) {
  // A 32-bit microsecond counter wraps every 4294.967296 s.
  Diagnostics diagnostics;
  TimestampSanitizer stamps(0.1, 4294.967296);
  EXPECT_DOUBLE_EQ(stamps.sanitize(4294.9, diagnostics, 1), 4294.9);
  EXPECT_NEAR(stamps.sanitize(0.032704, diagnostics, 2), 4295.0, 1e-9);
  EXPECT_NEAR(stamps.sanitize(0.132704, diagnostics, 3), 4295.1, 1e-9);
  EXPECT_EQ(diagnostics.count("timestamp_wrapped"), 1U);
  EXPECT_EQ(diagnostics.warnings(), 1U);
}

// ---- diagnostics -------------------------------------------------------------------------------------------------

TEST(Diagnostics, PrintsTheFirstFewOfEachKindAndCountsAll) {
  std::ostringstream err;
  Diagnostics diagnostics(&err, 3);
  for (int i = 0; i < 10; ++i) diagnostics.warn("truncated_line", static_cast<std::size_t>(i + 1), "cut");
  diagnostics.warn("non_numeric_field", 99, "bad");
  EXPECT_EQ(diagnostics.count("truncated_line"), 10U);
  EXPECT_EQ(diagnostics.warnings(), 11U);
  const std::string text = err.str();
  EXPECT_NE(text.find("[truncated_line] line 3: cut"), std::string::npos);
  EXPECT_EQ(text.find("line 4: cut"), std::string::npos);
  EXPECT_NE(text.find("further [truncated_line] warnings are counted but not printed"), std::string::npos);
  EXPECT_NE(text.find("[non_numeric_field] line 99: bad"), std::string::npos);
}

TEST(Formats, NamesRoundTripAndUnknownIsRejected) {
  for (const auto format : {LogFormat::carmen, LogFormat::dpslam, LogFormat::urg}) {
    EXPECT_EQ(parse_format(format_name(format)), format);
  }
  EXPECT_FALSE(parse_format("rosbag").has_value());
}

TEST(Poses, ComposeAndInverseAreConsistent) {
  const LogPose a{1.0, 2.0, 0.5}, b{-0.3, 0.7, -1.2};
  const LogPose ab = a.compose(b);
  const LogPose back = a.inverse().compose(ab);
  EXPECT_NEAR(back.x, b.x, 1e-12);
  EXPECT_NEAR(back.y, b.y, 1e-12);
  EXPECT_NEAR(back.theta, b.theta, 1e-12);
}

}  // namespace
}  // namespace occgeo::replay
