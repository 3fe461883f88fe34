#include "ltlo/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <iomanip>
#include <sstream>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "parsers.h"
#include "text_parse.h"

namespace ltlo::io {
namespace {

using detail::isCommentOrBlank;
using detail::LineReader;
using detail::parseFinite;
using detail::parseNanosecondsAsSeconds;
using detail::parseNumbers;
using detail::splitFields;
using detail::writeAtomically;

std::ifstream openForReading(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open trajectory file");
  return in;
}

// Quaternions are normalised: files printed with few decimals (TUM ground truth has 4) or by
// tools that do not renormalise are common. Norms further than kUnitTolerance from 1 are counted
// and reported in one warning per file; a zero or non-finite quaternion is an error.
constexpr double kUnitTolerance = 1e-3;

class QuaternionChecker {
 public:
  explicit QuaternionChecker(const std::string& path) : path_(path) {}

  Quat normalised(double w, double x, double y, double z, int line_number) {
    const double norm = std::sqrt(w * w + x * x + y * y + z * z);
    if (!std::isfinite(norm) || norm < 1e-6) {
      std::ostringstream os;
      os << "quaternion (qx qy qz qw) = (" << x << " " << y << " " << z << " " << w
         << ") has norm " << norm << ", cannot be normalised";
      throw InputError(path_, line_number, os.str());
    }
    if (std::abs(norm - 1.0) > kUnitTolerance) {
      if (num_not_unit_ == 0) first_line_ = line_number;
      ++num_not_unit_;
      min_norm_ = std::min(min_norm_, norm);
      max_norm_ = std::max(max_norm_, norm);
    }
    return Quat(w / norm, x / norm, y / norm, z / norm);
  }

  /// One warning for the whole file.
  void report(size_t num_poses) const {
    if (num_not_unit_ == 0) return;
    log::warn(path_, ":", first_line_, ": ", num_not_unit_, " of ", num_poses,
              " quaternions are not unit (norms ", min_norm_, " .. ", max_norm_,
              "); normalised", max_norm_ > 1.1 || min_norm_ < 0.9
                                    ? " (far from 1: are the columns in the expected order?)"
                                    : "");
  }

 private:
  std::string path_;
  size_t num_not_unit_ = 0;
  int first_line_ = 0;
  double min_norm_ = std::numeric_limits<double>::infinity();
  double max_norm_ = 0.0;
};

void checkIncreasing(const Trajectory& trajectory, double t_s, const std::string& path,
                     int line_number) {
  if (!trajectory.empty() && t_s <= trajectory.back().t_s) {
    std::ostringstream os;
    os << std::setprecision(16) << "timestamp " << t_s << " does not increase (previous "
       << trajectory.back().t_s << ")";
    throw InputError(path, line_number, os.str());
  }
}

// Nanoseconds nearest to t_s, computed from whole seconds and the (exact) fractional part:
// llround(t_s * 1e9) loses up to ~100 ns for Unix-epoch times because the product rounds.
int64_t secondsToNanoseconds(double t_s) {
  const double whole_s = std::floor(t_s);
  const int64_t fraction_ns = std::llround((t_s - whole_s) * 1e9);
  return static_cast<int64_t>(whole_s) * 1000000000LL + fraction_ns;
}

}  // namespace

namespace detail {

Trajectory parseTumTrajectory(std::istream& in, const std::string& path) {
  Trajectory trajectory;
  QuaternionChecker quaternions(path);
  LineReader lines(in);
  while (lines.next()) {
    if (isCommentOrBlank(lines.line())) continue;
    const std::vector<double> v =
        parseNumbers(lines.line(), ' ', 8, /*allow_extra=*/false, path, lines.number());
    checkIncreasing(trajectory, v[0], path, lines.number());
    const Quat q = quaternions.normalised(v[7], v[4], v[5], v[6], lines.number());
    trajectory.push_back({v[0], SE3(q, Vec3(v[1], v[2], v[3]))});
  }
  quaternions.report(trajectory.size());
  return trajectory;
}

Trajectory parseEurocTrajectory(std::istream& in, const std::string& path) {
  Trajectory trajectory;
  QuaternionChecker quaternions(path);
  LineReader lines(in);
  while (lines.next()) {
    const std::string& line = lines.line();
    const int line_number = lines.number();
    if (isCommentOrBlank(line)) continue;
    const std::vector<std::string> fields = splitFields(line, ',');
    if (fields.size() < 8) {
      throw InputError(
          path, line_number,
          "expected 8 values, found " + std::to_string(fields.size()) + " in '" + line + "'");
    }
    const double t_s = parseNanosecondsAsSeconds(fields[0], path, line_number);
    std::vector<double> v(8, 0.0);
    for (size_t i = 1; i < 8; ++i) {
      v[i] = parseFinite(fields[i], "value " + std::to_string(i + 1), path, line_number);
    }
    checkIncreasing(trajectory, t_s, path, line_number);
    const Quat q = quaternions.normalised(v[4], v[5], v[6], v[7], line_number);
    trajectory.push_back({t_s, SE3(q, Vec3(v[1], v[2], v[3]))});
  }
  quaternions.report(trajectory.size());
  return trajectory;
}

}  // namespace detail

Trajectory readTumTrajectory(const std::string& path) {
  std::ifstream in = openForReading(path);
  return detail::parseTumTrajectory(in, path);
}

Trajectory readEurocTrajectory(const std::string& path) {
  std::ifstream in = openForReading(path);
  return detail::parseEurocTrajectory(in, path);
}

// Timestamps with 9 decimals (ns); pose values with 17 significant digits so that a round trip
// reproduces the doubles (9 fixed decimals would lose ~1e-9 on quaternion components).
void writeTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  writeAtomically(path, [&](std::ostream& out) {
    out << "# timestamp tx ty tz qx qy qz qw\n";
    for (const StampedPose& pose : trajectory) {
      const Quat& q = pose.T_w_x.quaternion();
      const Vec3& t = pose.T_w_x.translation();
      out << std::fixed << std::setprecision(9) << pose.t_s << std::defaultfloat
          << std::setprecision(17) << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x()
          << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
    }
  });
}

void writeEurocTrajectory(const std::string& path, const Trajectory& trajectory) {
  writeAtomically(path, [&](std::ostream& out) {
    out << "#timestamp [ns],p_x [m],p_y [m],p_z [m],q_w [],q_x [],q_y [],q_z []\n";
    out << std::setprecision(17);
    for (const StampedPose& pose : trajectory) {
      const Quat& q = pose.T_w_x.quaternion();
      const Vec3& t = pose.T_w_x.translation();
      out << secondsToNanoseconds(pose.t_s) << ',' << t.x() << ',' << t.y() << ',' << t.z() << ','
          << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z() << '\n';
    }
  });
}

}  // namespace ltlo::io
