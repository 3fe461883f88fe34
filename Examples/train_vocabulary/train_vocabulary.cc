// train_vocabulary --images DIR --out FILE [--k K --levels L --crops N --max-images M]
// Trains a bow vocabulary on ORB features of random crops of every image under DIR (recursive).
// Progress goes to the log (stderr); the last stdout line is "vocabulary <file> nodes <n> words <w>".
// Exit status: 0 written, 2 bad input (options, image folder, output file), 1 any other error.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bow/vocabulary.h"
#include "ltlo/core/log.h"
#include "ltlo/features/orb_extractor.h"

namespace fs = std::filesystem;

namespace {

std::vector<std::string> findImages(const std::string& root) {
  std::vector<std::string> paths;
  for (const fs::directory_entry& entry :
       fs::recursive_directory_iterator(root, fs::directory_options::follow_directory_symlink)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".webp") paths.push_back(entry.path().string());
  }
  std::sort(paths.begin(), paths.end());  // directory order is not stable; the training must be
  return paths;
}

/// A random 4:3 crop of 25%..100% of the largest 4:3 window, resized to 640x480, with a random
/// exposure gain: one image yields many different VGA "views" at different scales.
cv::Mat randomCrop(const cv::Mat& image, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double max_w = std::min<double>(image.cols, image.rows * 4.0 / 3.0);
  const double w = max_w * (0.25 + 0.75 * unit(rng));
  const double h = w * 0.75;
  const int x = static_cast<int>(unit(rng) * (image.cols - w));
  const int y = static_cast<int>(unit(rng) * (image.rows - h));
  const cv::Rect rect(x, y, std::max(1, static_cast<int>(w)), std::max(1, static_cast<int>(h)));
  cv::Mat crop;
  cv::resize(image(rect & cv::Rect(0, 0, image.cols, image.rows)), crop, cv::Size(640, 480), 0, 0,
             w > 640 ? cv::INTER_AREA : cv::INTER_LINEAR);
  const double gain = 0.7 + 0.6 * unit(rng);
  crop.convertTo(crop, CV_8U, gain, 0.0);
  return crop;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Train a bag-of-words vocabulary from the ORB features of a folder of images"};
  std::string images_dir;
  std::string out_path;
  std::string text_path;
  int k = 10;
  int levels = 5;
  int crops = 40;
  int max_images = 0;
  std::size_t max_cluster = 2000000;
  std::uint64_t seed = 1;
  int threads = 2;
  app.add_option("--images", images_dir, "folder searched recursively for .jpg/.jpeg/.png/.webp")->required();
  app.add_option("--out", out_path, "output vocabulary (binary LTLOBOW1)")->required();
  app.add_option("--k", k, "branching factor")->check(CLI::Range(2, 255));
  app.add_option("--levels", levels, "tree depth L")->check(CLI::Range(1, 10));
  app.add_option("--crops", crops, "random crops per image")->check(CLI::Range(1, 10000));
  app.add_option("--max-images", max_images, "use at most this many images (0 = all)")->check(CLI::NonNegativeNumber);
  app.add_option("--max-cluster-descriptors", max_cluster, "cluster on a random subset of this size (0 = all)");
  app.add_option("--seed", seed, "random seed for crops and seeding");
  app.add_option("--threads", threads, "training threads")->check(CLI::Range(1, 64));
  app.add_option("--text", text_path, "also write a text export of the tree");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  ltlo::log::initFromEnvironment();

  try {
    const auto start = std::chrono::steady_clock::now();
    std::error_code error;
    if (!fs::is_directory(images_dir, error)) {
      std::fprintf(stderr, "train_vocabulary: %s: image folder does not exist\n", images_dir.c_str());
      return 2;
    }
    std::vector<std::string> paths = findImages(images_dir);
    if (max_images > 0 && static_cast<int>(paths.size()) > max_images) paths.resize(max_images);
    if (paths.empty()) {
      std::fprintf(stderr, "%s: no images found\n", images_dir.c_str());
      return 2;
    }
    const ltlo::features::OrbExtractor extractor(ltlo::features::OrbOptions{});
    std::mt19937_64 rng(seed);
    std::vector<std::vector<bow::Descriptor>> training;
    std::size_t num_descriptors = 0;
    for (std::size_t i = 0; i < paths.size(); ++i) {
      const cv::Mat image = cv::imread(paths[i], cv::IMREAD_GRAYSCALE);
      if (image.empty() || image.cols < 160 || image.rows < 120) {
        ltlo::log::warn(paths[i], ": unreadable or smaller than 160x120, skipped");
        continue;
      }
      for (int c = 0; c < crops; ++c) {
        const ltlo::features::OrbFeatures features = extractor.extract(randomCrop(image, rng));
        if (features.descriptors.empty()) continue;
        training.emplace_back(features.descriptors.begin(), features.descriptors.end());
        num_descriptors += features.descriptors.size();
      }
      ltlo::log::info("image ", i + 1, " / ", paths.size(), " ", paths[i], ": ", training.size(), " crops, ",
                      num_descriptors, " descriptors so far");
    }
    if (training.empty()) {
      std::fprintf(stderr, "%s: none of the %zu images gave ORB features (unreadable or smaller than 160x120)\n",
                   images_dir.c_str(), paths.size());
      return 2;
    }
    bow::TrainOptions options;
    options.branching = k;
    options.depth = levels;
    options.seed = seed;
    options.num_threads = threads;
    options.max_cluster_descriptors = max_cluster;
    options.progress = [](const std::string& message) { ltlo::log::info(message); };
    const bow::Vocabulary vocabulary = bow::Vocabulary::train(training, options);
    vocabulary.save(out_path);
    if (!text_path.empty()) vocabulary.saveText(text_path);
    const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ltlo::log::info("trained on ", training.size(), " crops of ", paths.size(), " images in ", elapsed_s, " s");
    std::printf("vocabulary %s nodes %zu words %zu\n", out_path.c_str(), vocabulary.numNodes(), vocabulary.numWords());
  } catch (const std::filesystem::filesystem_error& e) {
    std::fprintf(stderr, "train_vocabulary: %s\n", e.what());  // names the folder
    return 2;
  } catch (const bow::FileError& e) {
    std::fprintf(stderr, "train_vocabulary: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "train_vocabulary: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
