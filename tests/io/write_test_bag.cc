// write_test_bag: the test bag writer as a program, for measurements and documentation.
//
//   write_test_bag --out BAG                                  the io tests' small bag (16x12, 5 frames,
//                                                             realsense topics, separate accel/gyro)
//   write_test_bag --out BAG --from-folder DIR [--preset realsense-unite] [--png-colour]
//                                                             a DATA_FORMAT.md folder as a bag
//                                                             (writeBagFromFolder: DepthMapFactor 1000)
#include <cstdio>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "test_bag_writer.h"

int main(int argc, char** argv) {
  CLI::App app{"Writes a ROS 1 bag with the test bag writer (tests/io/test_bag_writer.h)"};
  std::string out, folder, preset = "realsense-unite";
  bool png_colour = false;
  app.add_option("--out", out, "bag to write")->required();
  app.add_option("--from-folder", folder, "sequence folder (DATA_FORMAT.md) to convert");
  app.add_option("--preset", preset, "topic names (bag_topics.h presets)");
  app.add_flag("--png-colour", png_colour, "colour as PNG CompressedImage (else bgr8 Image)");
  CLI11_PARSE(app, argc, argv);
  try {
    if (folder.empty()) {
      ltlo::io::test::writeTestBag(out, ltlo::io::test::TestBagSpec{});
    } else {
      ltlo::io::test::writeBagFromFolder(folder, out, ltlo::io::bagTopicPreset(preset), png_colour);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_test_bag: %s\n", e.what());
    return 2;
  }
  return 0;
}
