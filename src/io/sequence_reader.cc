#include "ltlo/io/sequence_reader.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/io/associate.h"
#include "parsers.h"
#include "png_decode.h"
#include "text_parse.h"

namespace ltlo::io {
namespace {

namespace fs = std::filesystem;
using detail::formatTime;
using detail::joinPath;

bool isFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool isDirectory(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

using detail::ListedImage;

void checkImageExists(const std::string& image_path, const std::string& list_path, int line) {
  if (!isFile(image_path)) {
    throw InputError(list_path, line, "image file does not exist: " + image_path);
  }
}

std::vector<ListedImage> readImageList(const std::string& dir, const std::string& list_path) {
  std::ifstream in(list_path);
  if (!in) throw InputError(list_path, 0, "cannot open image list");
  std::vector<ListedImage> images = detail::parseImageList(in, dir, list_path);
  for (const ListedImage& image : images) checkImageExists(image.path, list_path, image.line);
  if (images.empty()) {
    throw InputError(list_path, 0, "lists no images (only comments or blank lines)");
  }
  return images;
}

std::vector<FrameFiles> readAssociations(const std::string& dir, const std::string& list_path) {
  std::ifstream in(list_path);
  if (!in) throw InputError(list_path, 0, "cannot open associations file");
  std::vector<FrameFiles> frames = detail::parseAssociations(in, dir, list_path);
  for (const FrameFiles& frame : frames) {
    checkImageExists(frame.color_path, list_path, frame.color_list_line);
    checkImageExists(frame.depth_path, list_path, frame.depth_list_line);
  }
  if (frames.empty()) {
    throw InputError(list_path, 0, "lists no RGB-D frames (only comments or blank lines)");
  }
  return frames;
}

// Colour and depth lists paired by nearest timestamp (associateTimestamps); unpaired images are
// dropped with a log line.
std::vector<FrameFiles> associateLists(const std::vector<ListedImage>& colors,
                                       const std::string& color_list,
                                       const std::vector<ListedImage>& depths,
                                       const std::string& depth_list, double max_dt_s) {
  std::vector<double> color_times_s;
  std::vector<double> depth_times_s;
  for (const ListedImage& image : colors) color_times_s.push_back(image.t_s);
  for (const ListedImage& image : depths) depth_times_s.push_back(image.t_s);
  const std::vector<std::pair<int, int>> pairs =
      associateTimestamps(color_times_s, depth_times_s, max_dt_s);
  std::vector<FrameFiles> frames;
  for (const auto& [i, j] : pairs) {
    FrameFiles frame;
    frame.t_s = colors[i].t_s;
    frame.color_path = colors[i].path;
    frame.color_list_path = color_list;
    frame.color_list_line = colors[i].line;
    frame.depth_t_s = depths[j].t_s;
    frame.depth_path = depths[j].path;
    frame.depth_list_path = depth_list;
    frame.depth_list_line = depths[j].line;
    frames.push_back(frame);
  }
  if (frames.empty()) {
    throw InputError(color_list, 0,
                     "no RGB-D frames: none of the " + std::to_string(colors.size()) +
                         " colour images has a depth image in " + depth_list + " within " +
                         detail::formatTime(max_dt_s) + " s (" + std::to_string(depths.size()) +
                         " depth images from t = " + detail::formatTime(depths.front().t_s) +
                         " s; colour from t = " + detail::formatTime(colors.front().t_s) + " s)");
  }
  if (frames.size() < colors.size()) {
    log::info(color_list, ": ", colors.size() - frames.size(), " of ", colors.size(),
              " colour images have no depth image within ", max_dt_s, " s in ", depth_list);
  }
  return frames;
}

// masks/<timestamp>.png matched to frames by the number in the file name.
void attachMasks(const std::string& masks_dir, double max_dt_s, std::vector<FrameFiles>* frames) {
  std::vector<std::pair<double, std::string>> masks;
  for (const fs::directory_entry& entry : fs::directory_iterator(masks_dir)) {
    if (!entry.is_regular_file() || entry.path().extension() != ".png") continue;
    const std::string stem = entry.path().stem().string();
    masks.emplace_back(
        detail::parseFinite(stem, "mask file name timestamp", entry.path().string(), 0),
        entry.path().string());
  }
  std::sort(masks.begin(), masks.end());
  std::vector<double> mask_times_s;
  std::vector<double> frame_times_s;
  for (const auto& mask : masks) mask_times_s.push_back(mask.first);
  for (const FrameFiles& frame : *frames) frame_times_s.push_back(frame.t_s);
  for (const auto& [i, j] : associateTimestamps(frame_times_s, mask_times_s, max_dt_s)) {
    (*frames)[i].mask_path = masks[j].second;
  }
}

// Loads one image with its depth, type and size checked; messages name the index line and file.
cv::Mat loadImage(const std::string& image_path, int expected_type, const char* expected_text,
                  const std::string& list_path, int list_line) {
  cv::Mat image;
  try {
    image = readImageUnchanged(image_path);
  } catch (const cv::Exception& e) {
    throw InputError(list_path, list_line, image_path + ": cannot decode image (" + e.msg + ")");
  }
  if (image.empty()) {
    throw InputError(list_path, list_line, image_path + ": cannot read image");
  }
  if (image.type() != expected_type) {
    std::ostringstream os;
    os << image_path << ": expected " << expected_text << ", found " << image.channels()
       << " channel(s) of " << (image.elemSize1() * 8) << "-bit";
    throw InputError(list_path, list_line, os.str());
  }
  return image;
}

void checkSize(const cv::Mat& image, int width, int height, const std::string& what,
               const std::string& image_path, const std::string& list_path, int list_line) {
  if (image.cols != width || image.rows != height) {
    std::ostringstream os;
    os << image_path << ": size " << image.cols << "x" << image.rows << " differs from the " << what
       << " " << width << "x" << height;
    throw InputError(list_path, list_line, os.str());
  }
}

}  // namespace

cv::Mat SequenceReader::loadColorImage(const FrameFiles& files) const {
  cv::Mat image;
  try {
    image = readImageUnchanged(files.color_path);
  } catch (const cv::Exception& e) {
    throw InputError(files.color_list_path, files.color_list_line,
                     files.color_path + ": cannot decode image (" + e.msg + ")");
  }
  if (image.empty()) {
    throw InputError(files.color_list_path, files.color_list_line,
                     files.color_path + ": cannot read image");
  }
  if (image.type() == CV_8UC1 || image.type() == CV_8UC4) {
    // Benign variants: grey (some cameras, converted datasets) and BGRA (PNG with alpha).
    cv::Mat bgr(image.rows, image.cols, CV_8UC3);
    const int grey_to_bgr[] = {0, 0, 0, 1, 0, 2};
    const int bgra_to_bgr[] = {0, 0, 1, 1, 2, 2};
    cv::mixChannels(&image, 1, &bgr, 1, image.channels() == 1 ? grey_to_bgr : bgra_to_bgr, 3);
    if (!warned_color_conversion_->exchange(true)) {
      log::warn(files.color_path, ": ", image.channels() == 1 ? "8-bit grey" : "8-bit BGRA",
                " colour image converted to 3-channel BGR (warned once per sequence)");
    }
    return bgr;
  }
  if (image.type() != CV_8UC3) {
    std::ostringstream os;
    os << files.color_path << ": expected 8-bit colour (3-channel, or grey/BGRA converted), found "
       << image.channels() << " channel(s) of " << (image.elemSize1() * 8) << "-bit";
    throw InputError(files.color_list_path, files.color_list_line, os.str());
  }
  return image;
}

SequenceLayout detectLayout(const std::string& sequence_dir) {
  if (!isDirectory(sequence_dir)) {
    throw InputError(sequence_dir, 0, "sequence folder does not exist");
  }
  if (isFile(joinPath(sequence_dir, "color.txt"))) return SequenceLayout::kOpenLoris;
  if (isFile(joinPath(sequence_dir, "associations.txt")) ||
      isFile(joinPath(sequence_dir, "rgb.txt"))) {
    return SequenceLayout::kDataFormat;
  }
  throw InputError(sequence_dir, 0,
                   "unknown sequence layout: expected associations.txt or rgb.txt + depth.txt "
                   "(DATA_FORMAT.md), or color.txt + aligned_depth.txt (OpenLORIS-Scene)");
}

SequenceReader SequenceReader::open(const std::string& sequence_dir,
                                    const SequenceReaderOptions& options) {
  SequenceReader reader;
  reader.dir_ = sequence_dir;
  reader.imu_margin_s_ = options.imu_margin_s;
  reader.layout_ = detectLayout(sequence_dir);

  // Calibration first: image sizes are checked against it.
  const std::string calib_path = joinPath(sequence_dir, "calib.yaml");
  if (options.calib_override) {
    reader.calib_ = *options.calib_override;
  } else if (isFile(calib_path)) {
    reader.calib_ = SensorCalib::load(calib_path);
  } else {
    throw InputError(calib_path, 0,
                     "missing (this layout needs calibration from a settings file, pass one)");
  }

  // Frame index.
  if (reader.layout_ == SequenceLayout::kOpenLoris) {
    const std::string color_list = joinPath(sequence_dir, "color.txt");
    const std::string depth_list = joinPath(sequence_dir, "aligned_depth.txt");
    if (!isFile(depth_list)) throw InputError(depth_list, 0, "missing depth image list");
    reader.entries_ = associateLists(readImageList(sequence_dir, color_list), color_list,
                                     readImageList(sequence_dir, depth_list), depth_list,
                                     options.max_rgb_depth_dt_s);
  } else {
    const std::string associations = joinPath(sequence_dir, "associations.txt");
    if (isFile(associations)) {
      reader.entries_ = readAssociations(sequence_dir, associations);
    } else {
      const std::string color_list = joinPath(sequence_dir, "rgb.txt");
      const std::string depth_list = joinPath(sequence_dir, "depth.txt");
      if (!isFile(depth_list)) {
        throw InputError(depth_list, 0, "missing (needed without associations.txt)");
      }
      reader.entries_ = associateLists(readImageList(sequence_dir, color_list), color_list,
                                       readImageList(sequence_dir, depth_list), depth_list,
                                       options.max_rgb_depth_dt_s);
    }
  }

  if (!options.masks_dir) {
    // SEQ/masks/ is ground truth: opened only when asked for (diagnostics, evaluation, tests).
    const std::string masks_dir = joinPath(sequence_dir, "masks");
    if (options.read_masks && isDirectory(masks_dir)) attachMasks(masks_dir, options.max_mask_dt_s, &reader.entries_);
  } else if (!options.masks_dir->empty()) {
    if (!isDirectory(*options.masks_dir)) {
      throw InputError(*options.masks_dir, 0, "mask folder does not exist");
    }
    attachMasks(*options.masks_dir, options.max_mask_dt_s, &reader.entries_);
  }

  // IMU: imu.txt, else EuRoC imu0/data.csv, else OpenLORIS accel.txt + gyro.txt, else none.
  const std::string imu_txt = joinPath(sequence_dir, "imu.txt");
  const std::string euroc_csv = joinPath(sequence_dir, "imu0/data.csv");
  const std::string accel_txt = joinPath(sequence_dir, "accel.txt");
  const std::string gyro_txt = joinPath(sequence_dir, "gyro.txt");
  if (isFile(imu_txt)) {
    reader.imu_path_ = imu_txt;
    reader.imu_ = readImuText(imu_txt, options.sequence);
  } else if (isFile(euroc_csv)) {
    reader.imu_path_ = euroc_csv;
    reader.imu_ = readEurocImuCsv(euroc_csv, options.sequence);
  } else if (isFile(accel_txt) || isFile(gyro_txt)) {
    if (!isFile(accel_txt)) throw InputError(accel_txt, 0, "missing (gyro.txt is present)");
    if (!isFile(gyro_txt)) throw InputError(gyro_txt, 0, "missing (accel.txt is present)");
    reader.imu_path_ = accel_txt;
    reader.imu_ = readOpenLorisImu(accel_txt, gyro_txt, options.sequence);
  }
  if (reader.calib_.has_imu && reader.calib_.imu.time_offset_s != 0.0 && !reader.imu_.empty()) {
    // IMU.TimeOffset (t_imu = t_cam + offset): every stamp onto the camera's clock, once.
    const double offset_s = reader.calib_.imu.time_offset_s;
    for (ImuSample& sample : reader.imu_) sample.t_s -= offset_s;
    log::info(reader.imu_path_, ": IMU stamps moved onto the camera clock by IMU.TimeOffset = ", offset_s * 1e3, " ms");
  }
  if (!reader.imu_path_.empty() && reader.imu_.empty()) {
    log::warn(reader.imu_path_, ": no IMU samples (only comments or blank lines)");
  } else if (reader.calib_.has_imu && reader.imu_.empty()) {
    log::warn(sequence_dir, ": calibration has IMU keys but the sequence has no IMU file");
  }

  const std::string gt_path = joinPath(sequence_dir, "groundtruth.txt");
  if (isFile(gt_path)) {
    reader.ground_truth_path_ = gt_path;
    if (options.read_ground_truth) reader.ground_truth_ = readTumTrajectory(gt_path);
  }

  if (options.read_ground_truth || reader.ground_truth_path_.empty()) {
    log::info(sequence_dir, ": ", reader.entries_.size(), " frames, ", reader.imu_.size(),
              " IMU samples, ", reader.ground_truth_.size(), " ground-truth poses");
  } else {
    log::info(sequence_dir, ": ", reader.entries_.size(), " frames, ", reader.imu_.size(),
              " IMU samples; groundtruth.txt is read after the run (evaluation only)");
  }
  return reader;
}

void SequenceReader::seek(int index) {
  if (index < 0 || index > frameCount()) {
    throw InputError(dir_, 0, "first frame " + std::to_string(index) + " is outside the sequence's " +
                                  std::to_string(frameCount()) + " frames");
  }
  next_index_ = index;
}

std::optional<RgbdImuFrame> SequenceReader::next() {
  if (next_index_ >= frameCount()) return std::nullopt;
  return load(next_index_++);
}

RgbdImuFrame SequenceReader::load(int index, bool with_colour) const {
  LTLO_ASSERT(index >= 0 && index < frameCount(),
              "frame index " << index << " of " << frameCount());
  const FrameFiles& files = entries_[index];
  RgbdImuFrame frame;
  frame.index = index;
  frame.t_s = files.t_s;
  frame.depth_t_s = files.depth_t_s;
  frame.color_path = files.color_path;
  frame.depth_path = files.depth_path;
  frame.mask_path = files.mask_path;

  if (bag_) {
    loadBagImages(index, with_colour, &frame);
  } else {
    loadFolderImages(files, with_colour, &frame);
  }

  const double previous_t_s = index > 0 ? entries_[index - 1].t_s : files.t_s;
  frame.imu = imuSamplesBetween(imu_, previous_t_s - imu_margin_s_, files.t_s + imu_margin_s_);
  frame.imu_begin_s = previous_t_s;
  frame.imu_end_s = files.t_s;
  frame.imu_has_margin = imu_margin_s_ > 0.0;
  return frame;
}

void SequenceReader::loadFolderImages(const FrameFiles& files, bool with_colour, RgbdImuFrame* out) const {
  RgbdImuFrame& frame = *out;
  const int width = calib_.camera.camera.width();
  const int height = calib_.camera.camera.height();
  // Depth and mask are checked against the colour image when it is loaded (the messages name it),
  // else against the calibrated size.
  const char* reference = with_colour ? "colour image" : "calibrated image size";
  if (with_colour) {
    frame.color_bgr = loadColorImage(files);
    checkSize(frame.color_bgr, width, height, "calibrated image size", files.color_path,
              files.color_list_path, files.color_list_line);
  }
  const cv::Mat depth_raw = loadImage(files.depth_path, CV_16UC1, "16-bit 1-channel depth",
                                      files.depth_list_path, files.depth_list_line);
  checkSize(depth_raw, width, height, reference, files.depth_path, files.depth_list_path,
            files.depth_list_line);
  depth_raw.convertTo(frame.depth_m, CV_32F, 1.0 / calib_.camera.depth_map_factor);

  if (!files.mask_path.empty()) {
    // Messages name the frame's colour index line: the mask belongs to that frame.
    frame.mask = loadImage(files.mask_path, CV_8UC1, "8-bit 1-channel mask", files.color_list_path,
                           files.color_list_line);
    checkSize(frame.mask, width, height, reference, files.mask_path, files.color_list_path,
              files.color_list_line);
  }
}

}  // namespace ltlo::io
