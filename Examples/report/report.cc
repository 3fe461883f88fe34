// report: writes OUT/report.md (tables) and OUT/plots/*.png (trajectory top views, error and IoU
// over time, per-stage timing) for the finished runs of a scripts/benchmark.sh folder.
//
//   report --benchmark OUT [--title TEXT]
//
// Exit status: 0 done, 2 bad input (naming the file), 1 any other error.
#include <CLI/CLI.hpp>
#include <iostream>
#include <string>

#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/report/benchmark_report.h"

int main(int argc, char** argv) {
  ltlo::log::initFromEnvironment();
  CLI::App app{"Benchmark report: tables and plots of every finished run"};
  std::string benchmark_dir;
  std::string title = "LTLO-SLAM benchmark";
  app.add_option("--benchmark", benchmark_dir, "benchmark output folder (runs/ inside)")
      ->required();
  app.add_option("--title", title, "first line of the report (date, commit, machine)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "report: " << e.what() << "\n" << app.help();
    return 2;
  }
  try {
    const int runs = ltlo::report::writeBenchmarkReport(benchmark_dir, title);
    std::cout << "runs " << runs << "\nreport " << benchmark_dir << "/report.md\n";
  } catch (const ltlo::InputError& e) {
    std::cerr << "report: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "report: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
