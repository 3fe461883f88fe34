// simulate: writes a synthetic RGB-D-inertial sequence (DATA_FORMAT.md) for a scenario.
//   simulate --scenario static|stlo|mtlo|ltlo|carried --seed N --seconds S [--fps F] --out DIR
//            [--width 640 --height 480] [--config config_yaml/simulator.yaml] [--noise-free]
#include <CLI/CLI.hpp>
#include <iostream>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/core/settings_file.h"
#include "ltlo/sim/simulator.h"

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
  std::vector<double> black_outage, no_depth_outage;
  app.add_option("--black", black_outage,
                 "START,DURATION (s): black colour and no depth while the IMU runs (forced tracking loss)")
      ->delimiter(',')
      ->expected(2);
  app.add_option("--no-depth", no_depth_outage, "START,DURATION (s): frames without depth")
      ->delimiter(',')
      ->expected(2);
  app.add_option("--progress-every", progress_every, "progress line every N frames")
      ->check(CLI::Range(1, 1000000));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
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
    options.seed = static_cast<uint64_t>(seed);
    options.duration_s = seconds;
    options.noise_free = noise_free;
    if (fps > 0) options.fps = fps;
    if (width > 0) options.width_px = width;
    if (height > 0) options.height_px = height;
    using Outage = ltlo::sim::SensorOutage;
    if (!black_outage.empty())
      options.outages.push_back({Outage::Kind::kBlack, black_outage[0], black_outage[1]});
    if (!no_depth_outage.empty())
      options.outages.push_back({Outage::Kind::kNoDepth, no_depth_outage[0], no_depth_outage[1]});
    ltlo::sim::writeSequence(options, out_dir, progress_every);
  } catch (const ltlo::ConfigError& e) {
    std::cerr << e.what() << "\n";
    return 2;
  } catch (const ltlo::InputError& e) {
    std::cerr << e.what() << "\n";
    return 2;
  }
  return 0;
}
