// simulate: writes a synthetic RGB-D-inertial sequence (DATA_FORMAT.md) for a scenario.
//   simulate --scenario static|stlo|mtlo|ltlo|carried --seed N --seconds S [--fps F] --out DIR
//            [--width 640 --height 480] [--config config_yaml/simulator.yaml] [--noise-free]
//            [--black START,DURATION]... [--no-depth START,DURATION]... [--imu-gap START,DURATION]...
//            [--sensor ideal|realsense|kinect|FILE.yaml] [--sensor-set KEY=VALUE]...
//            [--time-offset S] [--lens none|radtan|radtan-strong|rational|kb]
//            [--still START,DURATION]... [--occlusion-at T]...
//            [--plain-movers] [--occluded-start away|towards] [--walkers N] [--door] [--three-movers]
// Exit status: 0 written, 2 bad input (options, config file, output folder), 1 any other error.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/sim/simulator.h"

namespace {

/// "START,DURATION" (s) of an outage option; throws InputError naming the option and the value.
ltlo::sim::SensorOutage parseOutage(const std::string& option, const std::string& text,
                                    ltlo::sim::SensorOutage::Kind kind) {
  const size_t comma = text.find(',');
  char* end_start = nullptr;
  char* end_duration = nullptr;
  const std::string start_text = text.substr(0, comma);
  const std::string duration_text = comma == std::string::npos ? "" : text.substr(comma + 1);
  const double start_s = std::strtod(start_text.c_str(), &end_start);
  const double duration_s = std::strtod(duration_text.c_str(), &end_duration);
  if (comma == std::string::npos || start_text.empty() || duration_text.empty() || *end_start != '\0' ||
      *end_duration != '\0' || !std::isfinite(start_s) || !std::isfinite(duration_s) || start_s < 0.0 ||
      duration_s <= 0.0) {
    throw ltlo::InputError(option + " " + text +
                           ": expected START,DURATION in seconds (START >= 0, DURATION > 0)");
  }
  return {kind, start_s, duration_s};
}

/// config_yaml/sensor_<name>.yaml of the profile `name`: under $LTLO_SOURCE_DIR, next to the build
/// tree of this executable (<root>/build/bin/simulate), the source tree it was built from, or the
/// working directory. A text with a '/' or ending in ".yaml" is a file path.
std::string sensorProfilePath(const std::string& text) {
  namespace fs = std::filesystem;
  if (text.find('/') != std::string::npos || (text.size() > 5 && text.substr(text.size() - 5) == ".yaml"))
    return text;
  std::vector<fs::path> roots;
  if (const char* env = std::getenv("LTLO_SOURCE_DIR")) roots.emplace_back(env);
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  if (!error) {
    roots.push_back(exe.parent_path().parent_path().parent_path());
    roots.push_back(exe.parent_path().parent_path());
  }
#ifdef LTLO_SOURCE_DIR_AT_BUILD
  roots.emplace_back(LTLO_SOURCE_DIR_AT_BUILD);
#endif
  roots.push_back(fs::current_path(error));
  const std::string name = "config_yaml/sensor_" + text + ".yaml";
  for (const fs::path& root : roots) {
    if (fs::is_regular_file(root / name, error)) return (root / name).string();
  }
  throw ltlo::InputError(name, 0, "--sensor " + text + ": no such profile (expected ideal, realsense, kinect or a FILE.yaml)");
}

/// The profile of --sensor (a shipped name or a file) with --sensor-set overrides; without either, the
/// built-in ideal sensor (no file read, the simulator's output of before profiles).
ltlo::sim::SensorProfile loadSensorProfile(const std::string& sensor, const std::vector<std::string>& sets) {
  if (sensor.empty() && sets.empty()) return ltlo::sim::SensorProfile();
  ltlo::SettingsFile file(sensorProfilePath(sensor.empty() ? "ideal" : sensor));
  for (const std::string& set : sets) {
    const size_t equals = set.find('=');
    if (equals == std::string::npos || equals == 0)
      throw ltlo::InputError("--sensor-set " + set + ": expected KEY=VALUE (e.g. Sensor.Drops.Enable=1)");
    file.setOverride(set.substr(0, equals), set.substr(equals + 1));
  }
  return ltlo::sim::SensorProfile::load(file);
}

}  // namespace

int main(int argc, char** argv) {
  ltlo::log::initFromEnvironment();
  CLI::App app{"Generate a synthetic RGB-D-inertial sequence with dynamic occlusions"};
  std::string scenario_text, out_dir, config_path;
  int64_t seed = 1;
  double seconds = 0.0, fps = 0.0;
  int width = 0, height = 0, progress_every = 100;
  bool noise_free = false;
  app.add_option("--scenario", scenario_text, "static|stlo|mtlo|ltlo|carried")->required();
  app.add_option("--seed", seed, "random seed (trajectory details, occlusions, noise)")
      ->required()
      ->check(CLI::Range(int64_t{0}, int64_t{1} << 40));
  app.add_option("--seconds", seconds, "sequence duration (s)")
      ->required()
      ->check(CLI::Range(0.1, 36000.0));
  app.add_option("--fps", fps, "frame rate (Hz, default from the config: 30)")
      ->check(CLI::Range(1.0, 200.0));
  app.add_option("--out", out_dir, "output directory")->required();
  app.add_option("--width", width, "image width (px, default 640)")->check(CLI::Range(16, 4096));
  app.add_option("--height", height, "image height (px, default 480)")->check(CLI::Range(16, 4096));
  app.add_option("--config", config_path, "simulator YAML (default: built-in values)");
  app.add_flag("--noise-free", noise_free, "no sensor noise, biases, holes or exposure jitter");
  std::vector<std::string> black_outages, no_depth_outages, imu_gaps;
  app.add_option("--black", black_outages,
                 "START,DURATION (s): black colour and no depth while the IMU runs (forced tracking "
                 "loss); repeatable");
  app.add_option("--no-depth", no_depth_outages, "START,DURATION (s): frames without depth; repeatable");
  app.add_option("--imu-gap", imu_gaps,
                 "START,DURATION (s): no IMU samples in imu.txt (dropped driver buffer); repeatable");
  std::string sensor_text, lens_text;
  std::vector<std::string> sensor_sets;
  double time_offset_s = std::nan("");
  app.add_option("--sensor", sensor_text,
                 "sensor profile: ideal|realsense|kinect (config_yaml/sensor_NAME.yaml) or FILE.yaml; default: the "
                 "built-in ideal sensor");
  app.add_option("--sensor-set", sensor_sets,
                 "KEY=VALUE: override one key of the profile (e.g. Sensor.Exposure.Enable=0); repeatable");
  app.add_option("--time-offset", time_offset_s,
                 "camera-IMU time offset (s, t_imu = t_cam + offset) in [-0.2, 0.2]; turns the fault on");
  app.add_option("--lens", lens_text, "lens of the raw images: none|radtan|radtan-strong|rational|kb");
  std::vector<std::string> stills;
  app.add_option("--still", stills,
                 "START,DURATION (s): the robot stands still (pose held; --still 0,3 = still start); repeatable");
  std::vector<double> occlusion_at;
  app.add_option("--occlusion-at", occlusion_at,
                 "T (s): a box crosses the view from T (in from one side, held 2-4 s, out to the other); repeatable")
      ->check(CLI::Range(0.0, 1e6));
  bool plain_movers = false, tall_panels = false, doors = false, three_movers = false;
  std::string occluded_start;
  int walkers = 0;
  app.add_flag("--plain-movers", plain_movers,
               "every mover one plain colour; half of the events are thin panels instead of boxes (as wide and "
               "tall as the box each replaces)");
  app.add_flag("--tall-panels", tall_panels,
               "with --plain-movers: panels 1.0-1.4 m wide and 1.5-2.0 m tall (up to twice a box; they hide the "
               "whole view when close)");
  app.add_option("--occluded-start", occluded_start,
                 "away|towards: a box covers 40-80 % of frame 0 and is pushed away or pulled towards the robot "
                 "at 1.5-3.5 s, gone by 5 s")
      ->check(CLI::IsMember({"away", "towards"}));
  app.add_option("--walkers", walkers, "N walking figures over the run (leading the robot or crossing its view)")
      ->check(CLI::Range(1, 100));
  app.add_flag("--door", doors, "door leaves swinging open and closed at three places the path passes");
  app.add_flag("--three-movers", three_movers,
               "a leading box, repeated crossing boxes and a carried box at once from t_clear on")
      ->excludes("--walkers");
  app.add_option("--progress-every", progress_every, "progress line every N frames")
      ->check(CLI::Range(1, 1000000));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  // CLI::Range lets NaN through (every comparison with it is false).
  if (!std::isfinite(seconds) || !std::isfinite(fps)) {
    std::cerr << "simulate: --seconds " << seconds << " / --fps " << fps << ": expected finite numbers\n";
    return 2;
  }
  try {
    ltlo::sim::SimOptions options;
    if (!config_path.empty())
      options = ltlo::sim::SimOptions::load(ltlo::SettingsFile(config_path));
    if (!ltlo::sim::parseScenario(scenario_text, &options.scenario)) {
      std::cerr << "--scenario " << scenario_text
                << ": expected static, stlo, mtlo, ltlo or carried\n";
      return 2;
    }
    options.sensor = loadSensorProfile(sensor_text, sensor_sets);
    if (!lens_text.empty()) {
      ltlo::sim::LensPreset preset;
      if (!ltlo::sim::parseLensPreset(lens_text, &preset)) {
        std::cerr << "simulate: --lens " << lens_text << ": expected none, radtan, radtan-strong, rational or kb\n";
        return 2;
      }
      options.sensor.lens_enable = preset != ltlo::sim::LensPreset::kNone;
      options.sensor.lens = ltlo::sim::lensPreset(preset);
    }
    if (!std::isnan(time_offset_s)) {
      if (!(std::abs(time_offset_s) <= 0.2)) {
        std::cerr << "simulate: --time-offset " << time_offset_s << ": expected seconds in [-0.2, 0.2]\n";
        return 2;
      }
      options.sensor.time_offset_enable = true;
      options.sensor.time_offset_s = time_offset_s;
    }
    options.seed = static_cast<uint64_t>(seed);
    options.duration_s = seconds;
    options.noise_free = noise_free;
    if (fps > 0) options.fps = fps;
    if (width > 0) options.width_px = width;
    if (height > 0) options.height_px = height;
    using Outage = ltlo::sim::SensorOutage;
    for (const std::string& text : black_outages)
      options.outages.push_back(parseOutage("--black", text, Outage::Kind::kBlack));
    for (const std::string& text : no_depth_outages)
      options.outages.push_back(parseOutage("--no-depth", text, Outage::Kind::kNoDepth));
    for (const std::string& text : imu_gaps)
      options.outages.push_back(parseOutage("--imu-gap", text, Outage::Kind::kImuGap));
    for (const std::string& text : stills) {
      const Outage parsed = parseOutage("--still", text, Outage::Kind::kBlack);
      options.stills.push_back({parsed.start_s, parsed.duration_s});
    }
    options.occlusion_at_s = occlusion_at;
    options.plain_movers = plain_movers;
    options.tall_panels = tall_panels;
    if (tall_panels && !plain_movers) {
      std::cerr << "simulate: --tall-panels needs --plain-movers\n";
      return 2;
    }
    if (!occluded_start.empty())
      options.occluded_start = occluded_start == "away" ? ltlo::sim::StartMove::kAway : ltlo::sim::StartMove::kTowards;
    options.walkers = walkers;
    options.doors = doors;
    options.three_movers = three_movers;
    ltlo::sim::writeSequence(options, out_dir, progress_every);
  } catch (const ltlo::ConfigError& e) {
    std::cerr << "simulate: " << e.what() << "\n";
    return 2;
  } catch (const ltlo::InputError& e) {
    std::cerr << "simulate: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
