// sim_preview: RGB | depth (colour-mapped, black = no reading) | mask side by side for frames of a
// generated sequence, one row per frame, written to one PNG.
//   sim_preview --sequence DIR --out FILE.png --frames 0,30,60 [--scale 0.5]
// Exit status: 0 written, 2 bad input (a missing or unreadable file, a frame index out of range,
// an output that cannot be written), 1 any other error.
#include <CLI/CLI.hpp>
#include <exception>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

/// Bad input: the message names the file and what is wrong with it.
struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Timestamps (file name stems) of rgb.txt, '#' comments and blank lines skipped.
std::vector<std::string> readStamps(const std::string& rgb_txt_path) {
  std::ifstream rgb_txt(rgb_txt_path);
  if (!rgb_txt) throw BadInput(rgb_txt_path + ": cannot open");
  std::vector<std::string> stamps;
  for (std::string line; std::getline(rgb_txt, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    stamps.push_back(line.substr(first, line.find_first_of(" \t", first) - first));
  }
  return stamps;
}

/// Reads one image of the expected OpenCV type.
cv::Mat readImage(const std::string& path, int flags, int expected_type, const char* expected_text) {
  cv::Mat image;
  try {
    image = cv::imread(path, flags);
  } catch (const cv::Exception& e) {
    throw BadInput(path + ": cannot decode (" + e.msg + ")");
  }
  if (image.empty()) throw BadInput(path + ": missing or not an image");
  if (image.type() != expected_type) throw BadInput(path + ": expected " + expected_text);
  return image;
}

cv::Mat previewRow(const std::string& sequence, const std::string& stamp, double scale) {
  const std::string name = stamp + ".png";
  const cv::Mat rgb = readImage(sequence + "/rgb/" + name, cv::IMREAD_COLOR, CV_8UC3, "colour");
  const cv::Mat depth =
      readImage(sequence + "/depth/" + name, cv::IMREAD_UNCHANGED, CV_16UC1, "16-bit depth");
  const cv::Mat mask =
      readImage(sequence + "/masks/" + name, cv::IMREAD_GRAYSCALE, CV_8UC1, "8-bit mask");
  if (depth.size() != rgb.size() || mask.size() != rgb.size()) {
    throw BadInput(sequence + ": " + name + ": colour, depth and mask sizes differ");
  }
  cv::Mat depth8, depth_colour, mask_colour, row;
  depth.convertTo(depth8, CV_8U, 255.0 / 5500.0);
  cv::applyColorMap(depth8, depth_colour, cv::COLORMAP_JET);
  depth_colour.setTo(cv::Scalar::all(0), depth == 0);
  cv::cvtColor(mask, mask_colour, cv::COLOR_GRAY2BGR);
  cv::hconcat(std::vector<cv::Mat>{rgb, depth_colour, mask_colour}, row);
  cv::resize(row, row, cv::Size(), scale, scale, cv::INTER_AREA);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Side-by-side preview of a generated sequence"};
  std::string sequence, out;
  std::vector<int> frames;
  double scale = 0.5;
  app.add_option("--sequence", sequence, "sequence directory")->required();
  app.add_option("--out", out, "output PNG")->required();
  app.add_option("--frames", frames, "frame indices")->delimiter(',')->required();
  app.add_option("--scale", scale, "scale factor")->check(CLI::Range(0.05, 2.0));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    const std::vector<std::string> stamps = readStamps(sequence + "/rgb.txt");
    std::vector<cv::Mat> rows;
    for (int index : frames) {
      if (index < 0 || index >= static_cast<int>(stamps.size())) {
        throw BadInput(sequence + "/rgb.txt: no frame " + std::to_string(index) + " (" +
                       std::to_string(stamps.size()) + " frames)");
      }
      rows.push_back(previewRow(sequence, stamps[index], scale));
      if (rows.back().cols != rows.front().cols) {
        throw BadInput(sequence + ": frame " + std::to_string(index) + " differs in size from frame " +
                       std::to_string(frames.front()));
      }
    }
    cv::Mat panel;
    cv::vconcat(rows, panel);
    bool written = false;
    try {
      written = cv::imwrite(out, panel);
    } catch (const cv::Exception& e) {
      throw BadInput(out + ": cannot write (" + e.msg + ")");
    }
    if (!written) throw BadInput(out + ": cannot write");
  } catch (const BadInput& e) {
    std::cerr << "sim_preview: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "sim_preview: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
