#include "test_sequence_writer.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "ltlo/io/trajectory_io.h"

namespace ltlo::io::test {
namespace fs = std::filesystem;

TempDir::TempDir(const std::string& name) {
  path_ =
      (fs::temp_directory_path() / ("ltlo_" + name + "_" + std::to_string(::getpid()))).string();
  fs::remove_all(path_);
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

SensorCalib testCalib(const TestSequenceSpec& spec) {
  SensorCalib calib;
  calib.camera.camera = PinholeCamera(20.0, 20.0, (spec.width - 1) / 2.0, (spec.height - 1) / 2.0,
                                      spec.width, spec.height);
  calib.camera.fps = spec.fps;
  calib.camera.depth_map_factor = 1000.0;
  calib.has_imu = spec.with_imu;
  calib.imu.rate_hz = spec.imu_rate_hz;
  return calib;
}

// Times go through their text form so that tests compare with exactly what readers parse.
double frameTime(const TestSequenceSpec& spec, int k) {
  return std::stod(timeText(spec.t0_s + k / spec.fps));
}

std::string timeText(double t_s) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6f", t_s);
  return buffer;
}

Vec3 testGyro(double t_s) { return Vec3(0.1 * t_s, 0.2, -0.3 * t_s); }
Vec3 testAcc(double t_s) { return Vec3(t_s, -0.5 * t_s, 9.81); }
int testDepthRaw(int u, int v, int k) { return 1000 + 10 * u + v + 100 * k; }
Vec3 testColor(int u, int v, int k) { return Vec3(10 * u, 10 * v, 20 * k); }

namespace {

void writeColor(const std::string& path, const TestSequenceSpec& spec, int k) {
  cv::Mat image(spec.height, spec.width, CV_8UC3);
  for (int v = 0; v < spec.height; ++v) {
    for (int u = 0; u < spec.width; ++u) {
      const Vec3 c = testColor(u, v, k);
      image.at<cv::Vec3b>(v, u) = cv::Vec3b(c.x(), c.y(), c.z());
    }
  }
  if (!cv::imwrite(path, image)) throw std::runtime_error("cannot write " + path);
}

void writeDepth(const std::string& path, const TestSequenceSpec& spec, int k) {
  cv::Mat image(spec.height, spec.width, CV_16UC1);
  for (int v = 0; v < spec.height; ++v) {
    for (int u = 0; u < spec.width; ++u) image.at<uint16_t>(v, u) = testDepthRaw(u, v, k);
  }
  if (!cv::imwrite(path, image)) throw std::runtime_error("cannot write " + path);
}

void writeMask(const std::string& path, const TestSequenceSpec& spec, int k) {
  cv::Mat mask(spec.height, spec.width, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, k + 1, 2)) = 255;  // a dynamic block growing with k
  if (!cv::imwrite(path, mask)) throw std::runtime_error("cannot write " + path);
}

std::vector<double> imuTimes(const TestSequenceSpec& spec, double rate_hz) {
  std::vector<double> times_s;
  const double t_end_s = frameTime(spec, spec.num_frames - 1) + 0.05;
  for (int k = 0;; ++k) {
    const double t_s = spec.t0_s - 0.05 + spec.imu_offset_s + k / rate_hz;
    if (t_s > t_end_s) break;
    times_s.push_back(std::stod(timeText(t_s)));
  }
  return times_s;
}

Trajectory groundTruth(const TestSequenceSpec& spec) {
  Trajectory trajectory;
  for (int k = 0; k < spec.num_frames; ++k) {
    const double t_s = frameTime(spec, k);
    trajectory.push_back({t_s, SE3(so3ExpQuat(Vec3(0.0, 0.1 * k, 0.0)), Vec3(0.1 * k, 0.0, 0.0))});
  }
  return trajectory;
}

}  // namespace

void writeDataFormatSequence(const std::string& dir, const TestSequenceSpec& spec) {
  fs::create_directories(dir + "/rgb");
  fs::create_directories(dir + "/depth");
  if (spec.with_masks) fs::create_directories(dir + "/masks");
  std::ostringstream rgb_txt, depth_txt, associations;
  rgb_txt << "# colour images\n";
  depth_txt << "# depth images\n";
  for (int k = 0; k < spec.num_frames; ++k) {
    const std::string t_rgb = timeText(frameTime(spec, k));
    const std::string t_depth = timeText(frameTime(spec, k) + spec.depth_offset_s);
    writeColor(dir + "/rgb/" + t_rgb + ".png", spec, k);
    writeDepth(dir + "/depth/" + t_depth + ".png", spec, k);
    if (spec.with_masks) writeMask(dir + "/masks/" + t_rgb + ".png", spec, k);
    rgb_txt << t_rgb << " rgb/" << t_rgb << ".png\n";
    depth_txt << t_depth << " depth/" << t_depth << ".png\n";
    associations << t_rgb << " rgb/" << t_rgb << ".png " << t_depth << " depth/" << t_depth
                 << ".png\n";
  }
  writeText(dir + "/rgb.txt", rgb_txt.str());
  writeText(dir + "/depth.txt", depth_txt.str());
  if (spec.with_associations) writeText(dir + "/associations.txt", associations.str());
  if (spec.with_imu) {
    std::ostringstream imu;
    imu << "# timestamp gx gy gz ax ay az\n";
    imu.precision(17);
    for (const double t_s : imuTimes(spec, spec.imu_rate_hz)) {
      const Vec3 g = testGyro(t_s);
      const Vec3 a = testAcc(t_s);
      imu << timeText(t_s) << ' ' << g.x() << ' ' << g.y() << ' ' << g.z() << ' ' << a.x() << ' '
          << a.y() << ' ' << a.z() << '\n';
    }
    writeText(dir + "/imu.txt", imu.str());
  }
  if (spec.with_calib) testCalib(spec).write(dir + "/calib.yaml");
  if (spec.with_groundtruth) writeTumTrajectory(dir + "/groundtruth.txt", groundTruth(spec));
}

void writeOpenLorisSequence(const std::string& dir, const TestSequenceSpec& spec,
                            double accel_rate_hz, double gyro_rate_hz) {
  fs::create_directories(dir + "/color");
  fs::create_directories(dir + "/aligned_depth");
  std::ostringstream color_txt, depth_txt;
  for (int k = 0; k < spec.num_frames; ++k) {
    const std::string t_text = timeText(frameTime(spec, k));
    writeColor(dir + "/color/" + t_text + ".png", spec, k);
    writeDepth(dir + "/aligned_depth/" + t_text + ".png", spec, k);
    color_txt << t_text << " color/" << t_text << ".png\n";
    depth_txt << t_text << " aligned_depth/" << t_text << ".png\n";
  }
  writeText(dir + "/color.txt", color_txt.str());
  writeText(dir + "/aligned_depth.txt", depth_txt.str());
  std::ostringstream accel, gyro;
  accel.precision(17);
  gyro.precision(17);
  for (const double t_s : imuTimes(spec, accel_rate_hz)) {
    const Vec3 a = testAcc(t_s);
    accel << timeText(t_s) << ' ' << a.x() << ' ' << a.y() << ' ' << a.z() << '\n';
  }
  for (const double t_s : imuTimes(spec, gyro_rate_hz)) {
    const Vec3 g = testGyro(t_s);
    gyro << timeText(t_s) << ' ' << g.x() << ' ' << g.y() << ' ' << g.z() << '\n';
  }
  writeText(dir + "/accel.txt", accel.str());
  writeText(dir + "/gyro.txt", gyro.str());
  writeTumTrajectory(dir + "/groundtruth.txt", groundTruth(spec));
}

void writeEurocImu(const std::string& dir, const TestSequenceSpec& spec) {
  fs::create_directories(dir + "/imu0");
  std::ostringstream csv;
  csv << "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y,w_RS_S_z,a_RS_S_x [m s^-2],a_RS_S_y,"
         "a_RS_S_z\n";
  csv.precision(17);
  for (const double t_s : imuTimes(spec, spec.imu_rate_hz)) {
    const long long t_ns = std::llround(t_s * 1e6) * 1000LL;  // microsecond grid, as imu.txt
    const Vec3 g = testGyro(t_s);
    const Vec3 a = testAcc(t_s);
    csv << t_ns << ',' << g.x() << ',' << g.y() << ',' << g.z() << ',' << a.x() << ',' << a.y()
        << ',' << a.z() << '\n';
  }
  writeText(dir + "/imu0/data.csv", csv.str());
  fs::remove(dir + "/imu.txt");
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path);
}

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

void replaceLine(const std::string& path, int line_number, const std::string& text) {
  std::istringstream in(readText(path));
  std::ostringstream out;
  std::string line;
  int current = 0;
  bool replaced = false;
  while (std::getline(in, line)) {
    ++current;
    if (current == line_number) {
      out << text << '\n';
      replaced = true;
    } else {
      out << line << '\n';
    }
  }
  if (!replaced) throw std::runtime_error(path + " has no line " + std::to_string(line_number));
  writeText(path, out.str());
}

}  // namespace ltlo::io::test
