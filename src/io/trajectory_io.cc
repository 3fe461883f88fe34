#include "ltlo/io/trajectory_io.h"

#include <cmath>
#include <cstdint>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "ltlo/core/errors.h"
#include "text_parse.h"

namespace ltlo::io {
namespace {

using detail::isCommentOrBlank;

std::ifstream openForReading(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open trajectory file");
  return in;
}

std::ofstream openForWriting(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw InputError(path, 0, "cannot open for writing");
  return out;
}

Quat checkedQuaternion(double w, double x, double y, double z, const std::string& path,
                       int line_number) {
  const double norm = std::sqrt(w * w + x * x + y * y + z * z);
  if (std::abs(norm - 1.0) > 1e-2) {
    std::ostringstream os;
    os << "quaternion norm " << norm << " is not 1";
    throw InputError(path, line_number, os.str());
  }
  return Quat(w, x, y, z).normalized();
}

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

Trajectory readTumTrajectory(const std::string& path) {
  std::ifstream in = openForReading(path);
  Trajectory trajectory;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (isCommentOrBlank(line)) continue;
    const std::vector<double> v =
        detail::parseNumbers(line, ' ', 8, /*allow_extra=*/false, path, line_number);
    checkIncreasing(trajectory, v[0], path, line_number);
    const Quat q = checkedQuaternion(v[7], v[4], v[5], v[6], path, line_number);
    trajectory.push_back({v[0], SE3(q, Vec3(v[1], v[2], v[3]))});
  }
  return trajectory;
}

// Timestamps with 9 decimals (ns); pose values with 17 significant digits so that a round trip
// reproduces the doubles (9 fixed decimals would lose ~1e-9 on quaternion components).
void writeTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = openForWriting(path);
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const StampedPose& pose : trajectory) {
    const Quat& q = pose.T_w_x.quaternion();
    const Vec3& t = pose.T_w_x.translation();
    out << std::fixed << std::setprecision(9) << pose.t_s << std::defaultfloat
        << std::setprecision(17) << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x()
        << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  if (!out) throw InputError(path, 0, "write failed");
}

Trajectory readEurocTrajectory(const std::string& path) {
  std::ifstream in = openForReading(path);
  Trajectory trajectory;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (isCommentOrBlank(line)) continue;
    const std::vector<std::string> fields = detail::splitFields(line, ',');
    if (fields.size() < 8) {
      throw InputError(
          path, line_number,
          "expected 8 values, found " + std::to_string(fields.size()) + " in '" + line + "'");
    }
    const double t_s = detail::parseNanosecondsAsSeconds(fields[0], path, line_number);
    std::vector<double> v(8, 0.0);
    for (size_t i = 1; i < 8; ++i) {
      v[i] = detail::parseFinite(fields[i], "value " + std::to_string(i + 1), path, line_number);
    }
    checkIncreasing(trajectory, t_s, path, line_number);
    const Quat q = checkedQuaternion(v[4], v[5], v[6], v[7], path, line_number);
    trajectory.push_back({t_s, SE3(q, Vec3(v[1], v[2], v[3]))});
  }
  return trajectory;
}

void writeEurocTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = openForWriting(path);
  out << "#timestamp [ns],p_x [m],p_y [m],p_z [m],q_w [],q_x [],q_y [],q_z []\n";
  out << std::setprecision(17);
  for (const StampedPose& pose : trajectory) {
    const Quat& q = pose.T_w_x.quaternion();
    const Vec3& t = pose.T_w_x.translation();
    out << secondsToNanoseconds(pose.t_s) << ',' << t.x() << ',' << t.y() << ',' << t.z() << ','
        << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z() << '\n';
  }
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo::io
