#include "ltlo/io/trajectory_io.h"

#include <cmath>
#include <cstdint>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "ltlo/core/errors.h"

namespace ltlo::io {
namespace {

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

bool isCommentOrBlank(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

// Parses exactly `count` numbers (separated by spaces or the given separator); throws with the
// offending token otherwise.
std::vector<double> parseNumbers(const std::string& line, char separator, size_t count,
                                 const std::string& path, int line_number) {
  std::string normalised = line;
  for (char& c : normalised) {
    if (c == separator || c == '\t' || c == '\r') c = ' ';
  }
  std::istringstream is(normalised);
  std::vector<double> values;
  std::string token;
  while (is >> token && values.size() < count) {
    char* end = nullptr;
    const double value = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0') {
      throw InputError(path, line_number, "not a number: '" + token + "'");
    }
    if (!std::isfinite(value)) throw InputError(path, line_number, "non-finite value '" + token + "'");
    values.push_back(value);
  }
  if (values.size() < count) {
    throw InputError(path, line_number,
                     "expected " + std::to_string(count) + " values, found " +
                         std::to_string(values.size()) + " in '" + line + "'");
  }
  return values;
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

}  // namespace

Trajectory readTumTrajectory(const std::string& path) {
  std::ifstream in = openForReading(path);
  Trajectory trajectory;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (isCommentOrBlank(line)) continue;
    const std::vector<double> v = parseNumbers(line, ' ', 8, path, line_number);
    checkIncreasing(trajectory, v[0], path, line_number);
    const Quat q = checkedQuaternion(v[7], v[4], v[5], v[6], path, line_number);
    trajectory.push_back({v[0], SE3(q, Vec3(v[1], v[2], v[3]))});
  }
  return trajectory;
}

void writeTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = openForWriting(path);
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const StampedPose& pose : trajectory) {
    const Quat& q = pose.T_w_x.quaternion();
    const Vec3& t = pose.T_w_x.translation();
    out << std::fixed << std::setprecision(9) << pose.t_s << std::setprecision(9) << ' ' << t.x()
        << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' '
        << q.w() << '\n';
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
    const std::vector<double> v = parseNumbers(line, ',', 8, path, line_number);
    const double t_s = v[0] * 1e-9;
    checkIncreasing(trajectory, t_s, path, line_number);
    const Quat q = checkedQuaternion(v[4], v[5], v[6], v[7], path, line_number);
    trajectory.push_back({t_s, SE3(q, Vec3(v[1], v[2], v[3]))});
  }
  return trajectory;
}

void writeEurocTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = openForWriting(path);
  out << "#timestamp [ns],p_x [m],p_y [m],p_z [m],q_w [],q_x [],q_y [],q_z []\n";
  for (const StampedPose& pose : trajectory) {
    const Quat& q = pose.T_w_x.quaternion();
    const Vec3& t = pose.T_w_x.translation();
    const auto t_ns = static_cast<int64_t>(std::llround(pose.t_s * 1e9));
    out << t_ns << std::fixed << std::setprecision(9) << ',' << t.x() << ',' << t.y() << ','
        << t.z() << ',' << q.w() << ',' << q.x() << ',' << q.y() << ',' << q.z() << '\n';
  }
  if (!out) throw InputError(path, 0, "write failed");
}

}  // namespace ltlo::io
