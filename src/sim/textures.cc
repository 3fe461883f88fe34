#include "textures.h"

#include <algorithm>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace ltlo::sim {
namespace {

// Photographs of the wallpaper packages (licences: see the sim README paragraph / scene.h).
// Large (>= 2500 px) photographs are decoded at 1/4 size, the others at 1/2 (JPEG scaled decoding
// is several times faster than a full decode and the textures are at most 960 px).
const struct {
  const char* name;
  bool large;
} kPhotoFiles[] = {
    {"Bridge_by_Sander_Klootwijk.jpg", true},
    {"Dragonfly_by_Bolly.jpg", true},
    {"Fossa_by_Jasper_Roks.jpg", true},
    {"Kleiber_by_Lukas_Baubkus.jpg", true},
    {"Wine_by_Jakkub_Mede.jpg", true},
    {"aitzgorri_by_Aitzol_Berasategi.jpg", true},
    {"friends_by_Aitzol_Berasategi.jpg", true},
    {"greentock_by_Peter_Nerlich.jpg", true},
    {"life_by_Aitzol_Berasategi.jpg", true},
    {"picosdeeuropa_by_Aitzol_Berasategi.jpg", true},
    {"seeding_by_Clements_Engelhardt.jpg", true},
    {"sunset_by_Aitzol_Berasategi.jpg", true},
    {"umang_by_Abhishek_Mudgal.jpg", true},
    {"free_by_Peter_Nerlich.jpg", true},
    {"analogpattern_by_Peter_Nerlich.jpg", true},
    {"Picture_0B_by_freespace.jpg", true},
    {"mate/nature/Aqua.jpg", false},
    {"mate/nature/Blinds.jpg", false},
    {"mate/nature/Dune.jpg", false},
    {"mate/nature/FreshFlower.jpg", false},
    {"mate/nature/Garden.jpg", false},
    {"mate/nature/GreenMeadow.jpg", false},
    {"mate/nature/LadyBird.jpg", false},
    {"mate/nature/RainDrops.jpg", false},
    {"mate/nature/Storm.jpg", false},
    {"mate/nature/Wood.jpg", false},
    {"mate/desktop/GreenTraditional.jpg", false},
    {"mate/abstract/Elephants.jpg", false},
};

bool fileExists(const std::string& path) { return std::ifstream(path).good(); }

cv::Mat cropToCover(const cv::Mat& image, cv::Size size, double zoom, double fx, double fy) {
  // Largest crop of the target aspect, shrunk by `zoom` >= 1, positioned at (fx, fy) in [0, 1].
  const double aspect = static_cast<double>(size.width) / size.height;
  double w = image.cols, h = image.rows;
  if (w / h > aspect)
    w = h * aspect;
  else
    h = w / aspect;
  w /= zoom;
  h /= zoom;
  const int x0 = static_cast<int>((image.cols - w) * fx);
  const int y0 = static_cast<int>((image.rows - h) * fy);
  cv::Mat out;
  cv::resize(
      image(cv::Rect(x0, y0, std::max(1, static_cast<int>(w)), std::max(1, static_cast<int>(h)))),
      out, size, 0, 0, cv::INTER_AREA);
  return out;
}

}  // namespace

std::vector<cv::Mat> loadPhotos(const std::string& dir, std::vector<std::string>* paths) {
  std::vector<cv::Mat> photos;
  for (const auto& file : kPhotoFiles) {
    const std::string path = dir + "/" + file.name;
    if (!fileExists(path)) continue;
    cv::Mat image =
        cv::imread(path, file.large ? cv::IMREAD_REDUCED_COLOR_4 : cv::IMREAD_REDUCED_COLOR_2);
    if (image.empty()) continue;
    if (image.cols > 1600) {
      const double s = 1600.0 / image.cols;
      cv::resize(image, image, cv::Size(), s, s, cv::INTER_AREA);
    }
    photos.push_back(image);
    if (paths) paths->push_back(path);
  }
  return photos;
}

std::vector<cv::Mat> proceduralPhotos(int count, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<cv::Mat> photos;
  const cv::Size size(512, 384);
  for (int i = 0; i < count; ++i) {
    cv::Mat acc(size, CV_32FC3, cv::Scalar::all(0));
    // Value noise at octaves 4 .. 256 cells, each octave half the amplitude of the previous.
    double amplitude = 1.0;
    for (int cells = 4; cells <= 128; cells *= 2) {
      cv::Mat coarse(cells * size.height / size.width + 1, cells, CV_32FC3);
      for (int r = 0; r < coarse.rows; ++r)
        for (int c = 0; c < coarse.cols; ++c)
          coarse.at<cv::Vec3f>(r, c) = cv::Vec3f(unit(rng), unit(rng), unit(rng));
      cv::Mat fine;
      cv::resize(coarse, fine, size, 0, 0, cells >= 32 ? cv::INTER_NEAREST : cv::INTER_CUBIC);
      acc += fine * amplitude;
      amplitude *= 0.6;
    }
    cv::normalize(acc, acc, 0, 255, cv::NORM_MINMAX);
    cv::Mat image;
    acc.convertTo(image, CV_8UC3);
    for (int k = 0; k < 40; ++k) {  // hard-edged shapes for corners
      const cv::Point p(static_cast<int>(unit(rng) * size.width),
                        static_cast<int>(unit(rng) * size.height));
      const int r = 3 + static_cast<int>(unit(rng) * 40);
      const cv::Scalar colour(255 * unit(rng), 255 * unit(rng), 255 * unit(rng));
      if (k % 2)
        cv::circle(image, p, r, colour, cv::FILLED, cv::LINE_AA);
      else
        cv::rectangle(image, cv::Rect(p.x, p.y, r, r * 2 / 3), colour, cv::FILLED);
    }
    photos.push_back(image);
  }
  return photos;
}

cv::Mat makeCollage(const std::vector<cv::Mat>& photos, int base, cv::Size size,
                    std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int n = static_cast<int>(photos.size());
  cv::Mat collage = cropToCover(photos[base % n], size, 1.0 + unit(rng), unit(rng), unit(rng));
  // Framed pictures from large to small: (count, min, max) as fractions of the texture width.
  const struct {
    int count;
    double min_frac, max_frac;
  } scales[] = {{3, 0.25, 0.45}, {6, 0.10, 0.22}, {14, 0.03, 0.08}};
  for (const auto& scale : scales) {
    for (int k = 0; k < scale.count; ++k) {
      const int w = std::max(
          6, static_cast<int>(size.width *
                              (scale.min_frac + (scale.max_frac - scale.min_frac) * unit(rng))));
      const int h = std::max(6, static_cast<int>(w * (0.6 + 0.9 * unit(rng))));
      if (w >= size.width - 4 || h >= size.height - 4) continue;
      const int x = static_cast<int>(unit(rng) * (size.width - w));
      const int y = static_cast<int>(unit(rng) * (size.height - h));
      const int other = (base + 1 + static_cast<int>(unit(rng) * (n - 1))) % n;
      const cv::Mat picture =
          cropToCover(photos[other], cv::Size(w, h), 1.0 + 3.0 * unit(rng), unit(rng), unit(rng));
      picture.copyTo(collage(cv::Rect(x, y, w, h)));
      const int border = std::max(1, w / 40);
      const double shade = unit(rng) < 0.5 ? 20 + 40 * unit(rng) : 200 + 50 * unit(rng);
      cv::rectangle(collage, cv::Rect(x, y, w, h), cv::Scalar::all(shade), border);
    }
  }
  return collage;
}

}  // namespace ltlo::sim
