// sim_preview: RGB | depth (colour-mapped, black = no reading) | mask side by side for frames of a
// generated sequence, one row per frame, written to one PNG.
//   sim_preview --sequence DIR --out FILE.png --frames 0,30,60 [--scale 0.5]
#include <CLI/CLI.hpp>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <vector>

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
  std::ifstream rgb_txt(sequence + "/rgb.txt");
  std::vector<std::string> stamps;
  for (std::string line; std::getline(rgb_txt, line);) {
    if (line.empty() || line[0] == '#') continue;
    stamps.push_back(line.substr(0, line.find(' ')));
  }
  std::vector<cv::Mat> rows;
  for (int index : frames) {
    if (index < 0 || index >= static_cast<int>(stamps.size())) {
      std::cerr << sequence << "/rgb.txt: no frame " << index << " (" << stamps.size()
                << " frames)\n";
      return 2;
    }
    const std::string name = stamps[index] + ".png";
    const cv::Mat rgb = cv::imread(sequence + "/rgb/" + name);
    const cv::Mat depth = cv::imread(sequence + "/depth/" + name, cv::IMREAD_UNCHANGED);
    const cv::Mat mask = cv::imread(sequence + "/masks/" + name, cv::IMREAD_GRAYSCALE);
    if (rgb.empty() || depth.empty() || mask.empty()) {
      std::cerr << sequence << ": cannot read " << name << "\n";
      return 2;
    }
    cv::Mat depth8, depth_colour, mask_colour, row;
    depth.convertTo(depth8, CV_8U, 255.0 / 5500.0);
    cv::applyColorMap(depth8, depth_colour, cv::COLORMAP_JET);
    depth_colour.setTo(cv::Scalar::all(0), depth == 0);
    cv::cvtColor(mask, mask_colour, cv::COLOR_GRAY2BGR);
    cv::hconcat(std::vector<cv::Mat>{rgb, depth_colour, mask_colour}, row);
    cv::resize(row, row, cv::Size(), scale, scale, cv::INTER_AREA);
    rows.push_back(row);
  }
  cv::Mat panel;
  cv::vconcat(rows, panel);
  return cv::imwrite(out, panel) ? 0 : 2;
}
