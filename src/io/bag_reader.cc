// SequenceReader::openBag and the bag topic table: ROS 1 bags through Debian's rosbag_storage.
// The bag's index is read at open (rosbag keeps it in memory: tens of bytes per message), with the
// header stamps of every colour and depth message; load() instantiates one message per image
// under the bag's lock and decodes it outside the lock, so frames stream like image files.
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <iomanip>
#include <map>
#include <mutex>
#include <numeric>
#include <sstream>

#include "bag_messages.h"
#include "imu_streams.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "ltlo/io/associate.h"
#include "ltlo/io/sequence_reader.h"
#include "text_parse.h"

namespace ltlo::io::detail {
namespace {
/// The first fields of every sensor_msgs message with a std_msgs/Header: enough to index a topic
/// by header stamp without copying the image data ("*": rosbag accepts it for any message type).
struct HeaderStamp {
  uint32_t seq = 0;
  uint32_t sec = 0;
  uint32_t nsec = 0;
};
}  // namespace
}  // namespace ltlo::io::detail

namespace ros::message_traits {
template <>
struct MD5Sum<ltlo::io::detail::HeaderStamp> {
  static const char* value() { return "*"; }
  static const char* value(const ltlo::io::detail::HeaderStamp&) { return value(); }
};
template <>
struct DataType<ltlo::io::detail::HeaderStamp> {
  static const char* value() { return "*"; }
  static const char* value(const ltlo::io::detail::HeaderStamp&) { return value(); }
};
template <>
struct Definition<ltlo::io::detail::HeaderStamp> {
  static const char* value() { return ""; }
  static const char* value(const ltlo::io::detail::HeaderStamp&) { return value(); }
};
}  // namespace ros::message_traits

namespace ros::serialization {
template <>
struct Serializer<ltlo::io::detail::HeaderStamp> {
  template <typename Stream>
  static void read(Stream& stream, ltlo::io::detail::HeaderStamp& header) {
    stream.next(header.seq);
    stream.next(header.sec);
    stream.next(header.nsec);
  }
};
}  // namespace ros::serialization

namespace ltlo::io {
namespace detail {

/// The open bag, its image messages in frame order and the lock every read takes (rosbag::Bag
/// keeps one file position and chunk buffer).
class BagSource {
 public:
  std::string path;
  std::string color_topic, depth_topic;
  bool color_compressed = false, depth_compressed = false;
  /// Per frame: the colour and depth message and its 1-based number on its topic (messages).
  struct FrameMessages {
    rosbag::MessageInstance color;
    rosbag::MessageInstance depth;
    long color_number = 0;
    long depth_number = 0;
  };
  std::vector<FrameMessages> frames;
  std::string calib_source;
  mutable std::mutex mutex;
  mutable rosbag::Bag bag;
  mutable std::atomic<bool> warned_conversion{false};

  std::string where(const std::string& topic, long number) const {
    return path + ": topic " + topic + " message " + std::to_string(number);
  }
};

}  // namespace detail

namespace {

using detail::BagSource;
using detail::formatTime;
namespace fs = std::filesystem;

constexpr const char* kImageType = "sensor_msgs/Image";
constexpr const char* kCompressedType = "sensor_msgs/CompressedImage";
constexpr const char* kImuType = "sensor_msgs/Imu";
constexpr const char* kCameraInfoType = "sensor_msgs/CameraInfo";

void openBagFile(rosbag::Bag& bag, const std::string& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError(path, 0, "bag file does not exist");
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagUnindexedException& e) {
    throw InputError(path, 0, std::string("unindexed bag (") + e.what() +
                                  "); the recording was not closed: run `rosbag reindex " + path + "`");
  } catch (const rosbag::BagException& e) {
    throw InputError(path, 0, std::string("cannot read the bag (") + e.what() +
                                  "); a truncated or unindexed bag: try `rosbag reindex " + path + "`");
  }
}

std::vector<BagTopicInfo> topicTable(const rosbag::Bag& bag) {
  std::map<std::string, std::string> types;
  rosbag::View all(bag);
  for (const rosbag::ConnectionInfo* connection : all.getConnections()) {
    types.emplace(connection->topic, connection->datatype);
  }
  std::vector<BagTopicInfo> table;
  for (const auto& [topic, type] : types) {
    rosbag::View view(bag, rosbag::TopicQuery(topic));
    BagTopicInfo info;
    info.topic = topic;
    info.type = type;
    info.count = static_cast<long>(view.size());
    if (info.count > 0) {
      info.begin_s = view.getBeginTime().toSec();
      info.end_s = view.getEndTime().toSec();
    }
    if (info.count > 1 && info.end_s > info.begin_s) info.rate_hz = (info.count - 1) / (info.end_s - info.begin_s);
    table.push_back(info);
  }
  return table;
}

std::string topicList(const std::vector<BagTopicInfo>& table) {
  if (table.empty()) return "the bag has no topics";
  std::string text = "the bag has:";
  for (const BagTopicInfo& info : table) {
    text += " " + info.topic + " (" + info.type + ", " + std::to_string(info.count) + " messages);";
  }
  text.pop_back();
  return text;
}

// The topic's entry, or InputError naming the option and listing the bag's topics.
const BagTopicInfo& requireTopic(const std::vector<BagTopicInfo>& table, const std::string& topic,
                                 const std::string& option, const std::vector<std::string>& types,
                                 const std::string& path) {
  for (const BagTopicInfo& info : table) {
    if (info.topic != topic) continue;
    if (std::find(types.begin(), types.end(), info.type) == types.end()) {
      std::string expected;
      for (const std::string& type : types) expected += (expected.empty() ? "" : " or ") + type;
      throw InputError(path, 0, "topic " + topic + " (" + option + ") is " + info.type + ", expected " + expected);
    }
    if (info.count == 0) throw InputError(path, 0, "topic " + topic + " (" + option + ") has no messages");
    return info;
  }
  throw InputError(path, 0, "no topic " + topic + " (" + option + "); " + topicList(table));
}

// A topic's messages in bag order with their header stamps.
struct StampedMessages {
  std::vector<rosbag::MessageInstance> messages;
  std::vector<double> stamps_s;
};
StampedMessages readStamps(const BagSource& source, const std::string& topic) {
  StampedMessages result;
  rosbag::View view(source.bag, rosbag::TopicQuery(topic));
  long number = 0;
  for (const rosbag::MessageInstance& message : view) {
    ++number;
    boost::shared_ptr<detail::HeaderStamp> header;
    try {
      header = message.instantiate<detail::HeaderStamp>();
    } catch (const std::exception& e) {
      throw InputError(source.where(topic, number) + ": cannot read the message (" + e.what() + ")");
    }
    result.messages.push_back(message);
    result.stamps_s.push_back(detail::stampSeconds(header->sec, header->nsec));
  }
  return result;
}

// Frame order = header stamp order; a stamp repeated on the topic keeps its first message.
std::vector<int> stampOrder(const StampedMessages& stamped, const std::string& where_topic) {
  std::vector<int> order(stamped.stamps_s.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return stamped.stamps_s[a] < stamped.stamps_s[b]; });
  std::vector<int> kept;
  size_t moved = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    if (!kept.empty() && stamped.stamps_s[order[i]] == stamped.stamps_s[kept.back()]) continue;
    if (order[i] != static_cast<int>(i)) ++moved;
    kept.push_back(order[i]);
  }
  if (kept.size() < order.size() || moved > 0) {
    log::warn(where_topic, ": ", order.size() - kept.size(), " repeated header stamps dropped, ", moved,
              " messages out of stamp order sorted");
  }
  return kept;
}

// IMU messages as readings: the gyroscope, the accelerometer or both (values 0..2 = the one
// sensor; 0..5 = gyro then acc). Numbers are 1-based message numbers (the "lines" of messages).
detail::ReadingStream readImuTopic(const BagSource& source, const std::string& topic, bool gyro, bool acc) {
  detail::ReadingStream stream;
  rosbag::View view(source.bag, rosbag::TopicQuery(topic));
  int number = 0;
  for (const rosbag::MessageInstance& message : view) {
    ++number;
    const boost::shared_ptr<sensor_msgs::Imu> imu = message.instantiate<sensor_msgs::Imu>();
    if (!imu) throw InputError(source.where(topic, number) + ": not a sensor_msgs/Imu");
    detail::StampedReading reading;
    reading.t_s = detail::stampSeconds(imu->header.stamp.sec, imu->header.stamp.nsec);
    reading.line = number;
    const double w[3] = {imu->angular_velocity.x, imu->angular_velocity.y, imu->angular_velocity.z};
    const double a[3] = {imu->linear_acceleration.x, imu->linear_acceleration.y, imu->linear_acceleration.z};
    for (int k = 0; k < 3; ++k) {
      if (gyro) reading.values[k] = w[k];
      if (acc) reading.values[gyro ? k + 3 : k] = a[k];
    }
    for (double value : reading.values) {
      if (!std::isfinite(value)) throw InputError(source.where(topic, number) + ": non-finite IMU value");
    }
    stream.push_back(reading);
  }
  return stream;
}

void orderStream(detail::ReadingStream* stream, const std::string& path, const SequenceOptions& options) {
  const detail::OrderCounts counts = detail::putInTimeOrder(stream, path, options.max_imu_reorder_s);
  if (counts.any()) log::warn(detail::orderWarning(path, counts, ""));
  detail::checkImuGaps(*stream, path, "", options);
}

ImuSamples readBagImu(const BagSource& source, const std::vector<BagTopicInfo>& table, const BagTopics& topics,
                      const SequenceOptions& options, std::string* imu_path) {
  const std::vector<std::string> imu_type = {kImuType};
  if (!topics.imu.empty()) {
    requireTopic(table, topics.imu, "--imu-topic", imu_type, source.path);
    *imu_path = source.path + ":" + topics.imu;
    detail::ReadingStream stream = readImuTopic(source, topics.imu, true, true);
    orderStream(&stream, *imu_path, options);
    return detail::toImuSamples(stream);
  }
  if (topics.accel.empty() && topics.gyro.empty()) return {};
  if (topics.accel.empty() || topics.gyro.empty()) {
    throw InputError(source.path, 0, "separate IMU topics need both --accel-topic and --gyro-topic (given: " +
                                         (topics.accel.empty() ? topics.gyro : topics.accel) + ")");
  }
  requireTopic(table, topics.accel, "--accel-topic", imu_type, source.path);
  requireTopic(table, topics.gyro, "--gyro-topic", imu_type, source.path);
  const std::string accel_path = source.path + ":" + topics.accel;
  const std::string gyro_path = source.path + ":" + topics.gyro;
  detail::ReadingStream accel = readImuTopic(source, topics.accel, false, true);
  detail::ReadingStream gyro = readImuTopic(source, topics.gyro, true, false);
  orderStream(&accel, accel_path, options);
  orderStream(&gyro, gyro_path, options);
  // Merged as the OpenLORIS accel.txt + gyro.txt: at the union of both stamps, each interpolated.
  detail::MergeSummary summary;
  ImuSamples samples =
      detail::mergeImuStreams(gyro, gyro_path, accel, accel_path, detail::MergeTimes::kUnion, &summary);
  log::info(gyro_path, " + ", accel_path, ": merged at the union of their stamps inside [",
            formatTime(summary.begin_s), ", ", formatTime(summary.end_s), "] s, ", samples.size(), " samples (",
            summary.num_dropped, " stamps outside it dropped)");
  *imu_path = accel_path;
  return samples;
}

std::optional<CameraCalib> readCameraInfo(const BagSource& source, const std::vector<BagTopicInfo>& table,
                                          const std::string& topic) {
  if (topic.empty()) return std::nullopt;
  const bool present = std::any_of(table.begin(), table.end(), [&](const BagTopicInfo& i) { return i.topic == topic; });
  if (!present) {
    log::info(source.path, ": no CameraInfo topic ", topic);
    return std::nullopt;
  }
  requireTopic(table, topic, "camera_info", {kCameraInfoType}, source.path);
  rosbag::View view(source.bag, rosbag::TopicQuery(topic));
  const boost::shared_ptr<sensor_msgs::CameraInfo> info = view.begin()->instantiate<sensor_msgs::CameraInfo>();
  return detail::cameraCalibFromInfo(*info, source.where(topic, 1));
}

}  // namespace

SequenceReader SequenceReader::openBag(const std::string& bag_path, const BagTopics& topics,
                                       const SequenceReaderOptions& options) {
  auto source = std::make_shared<BagSource>();
  source->path = bag_path;
  openBagFile(source->bag, bag_path);
  const std::vector<BagTopicInfo> table = topicTable(source->bag);
  if (topics.rgb.empty() || topics.depth.empty()) {
    throw InputError(bag_path, 0, "give the colour and depth topics (--rgb-topic, --depth-topic or --bag-preset); " +
                                      topicList(table));
  }
  const std::vector<std::string> image_types = {kImageType, kCompressedType};
  source->color_topic = topics.rgb;
  source->depth_topic = topics.depth;
  source->color_compressed = requireTopic(table, topics.rgb, "--rgb-topic", image_types, bag_path).type == kCompressedType;
  source->depth_compressed = requireTopic(table, topics.depth, "--depth-topic", image_types, bag_path).type == kCompressedType;

  SequenceReader reader;
  reader.dir_ = bag_path;
  reader.imu_margin_s_ = options.imu_margin_s;

  // Frames: colour and depth by header stamp, associated as the folder reader's rgb.txt + depth.txt.
  const StampedMessages colors = readStamps(*source, topics.rgb);
  const StampedMessages depths = readStamps(*source, topics.depth);
  const std::vector<int> color_order = stampOrder(colors, bag_path + ": topic " + topics.rgb);
  const std::vector<int> depth_order = stampOrder(depths, bag_path + ": topic " + topics.depth);
  std::vector<double> color_times_s, depth_times_s;
  for (int i : color_order) color_times_s.push_back(colors.stamps_s[i]);
  for (int j : depth_order) depth_times_s.push_back(depths.stamps_s[j]);
  const std::vector<std::pair<int, int>> pairs =
      associateTimestamps(color_times_s, depth_times_s, options.max_rgb_depth_dt_s);
  if (pairs.empty()) {
    throw InputError(bag_path, 0, "no RGB-D frames: none of the " + std::to_string(color_times_s.size()) +
                                      " colour messages (" + topics.rgb + ", from t = " + formatTime(color_times_s.front()) +
                                      " s) has a depth message (" + topics.depth + ", from t = " +
                                      formatTime(depth_times_s.front()) + " s) within " +
                                      formatTime(options.max_rgb_depth_dt_s) + " s");
  }
  if (pairs.size() < color_times_s.size()) {
    log::info(bag_path, ": ", color_times_s.size() - pairs.size(), " of ", color_times_s.size(),
              " colour messages have no depth message within ", options.max_rgb_depth_dt_s, " s");
  }
  for (const auto& [i, j] : pairs) {
    const int color_index = color_order[i];
    const int depth_index = depth_order[j];
    source->frames.push_back({colors.messages[color_index], depths.messages[depth_index], color_index + 1L,
                              depth_index + 1L});
    FrameFiles files;
    files.t_s = color_times_s[i];
    files.depth_t_s = depth_times_s[j];
    // Not file paths: "<bag>:<topic>#<message>" names the message in logs and errors.
    files.color_path = bag_path + ":" + topics.rgb + "#" + std::to_string(color_index + 1);
    files.depth_path = bag_path + ":" + topics.depth + "#" + std::to_string(depth_index + 1);
    files.color_list_path = bag_path;
    files.depth_list_path = bag_path;
    reader.entries_.push_back(files);
  }

  // Calibration: the given one, CameraInfo's camera in place of its camera part when preferred.
  const std::optional<CameraCalib> info = readCameraInfo(*source, table, topics.camera_info);
  const std::string info_name = bag_path + ":" + topics.camera_info;
  if (options.calib_override) {
    reader.calib_ = *options.calib_override;
    source->calib_source = options.calib_override_source.empty() ? "the given calibration" : options.calib_override_source;
    if (info && !detail::sameCamera(*info, reader.calib_.camera)) {
      log::warn(info_name, ": CameraInfo ", detail::describeCamera(*info), " differs from ", source->calib_source, " ",
                detail::describeCamera(reader.calib_.camera), "; using ",
                options.prefer_camera_info ? "CameraInfo" : source->calib_source);
    }
    if (info && options.prefer_camera_info) {
      reader.calib_.camera.camera = info->camera;
      reader.calib_.camera.lens = info->lens;
      source->calib_source = info_name;
    }
  } else if (info) {
    reader.calib_.camera = *info;
    if (color_times_s.size() > 1) {
      reader.calib_.camera.fps = (color_times_s.size() - 1) / (color_times_s.back() - color_times_s.front());
    }
    source->calib_source = info_name;
  } else {
    throw InputError(bag_path, 0, "no calibration: " +
                                      (topics.camera_info.empty() ? std::string("no CameraInfo topic given")
                                                                  : "no CameraInfo topic " + topics.camera_info) +
                                      " and no calibration file (give --calib FILE, a calib.yaml of DATA_FORMAT.md)");
  }

  reader.imu_ = readBagImu(*source, table, topics, options.sequence, &reader.imu_path_);
  if (reader.calib_.has_imu && reader.calib_.imu.time_offset_s != 0.0 && !reader.imu_.empty()) {
    const double offset_s = reader.calib_.imu.time_offset_s;
    for (ImuSample& sample : reader.imu_) sample.t_s -= offset_s;
    log::info(reader.imu_path_, ": IMU stamps moved onto the camera clock by IMU.TimeOffset = ", offset_s * 1e3, " ms");
  }
  log::info(bag_path, ": ", reader.entries_.size(), " frames (", topics.rgb, ", ", topics.depth, "), ",
            reader.imu_.size(), " IMU samples; calibration from ", source->calib_source);
  reader.bag_ = source;
  return reader;
}

void SequenceReader::loadBagImages(int index, bool with_colour, RgbdImuFrame* frame) const {
  const BagSource& source = *bag_;
  const BagSource::FrameMessages& messages = source.frames.at(index);
  boost::shared_ptr<sensor_msgs::Image> color_raw, depth_raw;
  boost::shared_ptr<sensor_msgs::CompressedImage> color_packed, depth_packed;
  const std::string color_where = source.where(source.color_topic, messages.color_number);
  const std::string depth_where = source.where(source.depth_topic, messages.depth_number);
  {
    // rosbag reads through one file position and chunk buffer: one reader at a time; decoding
    // below runs unlocked.
    std::lock_guard<std::mutex> lock(source.mutex);
    auto instantiate = [](const rosbag::MessageInstance& message, const std::string& where, auto* out) {
      try {
        *out = message.template instantiate<typename std::remove_reference_t<decltype(**out)>>();
      } catch (const std::exception& e) {
        throw InputError(where + ": cannot read the message (" + e.what() + "); a damaged bag?");
      }
      if (!*out) throw InputError(where + ": message type changed within the topic");
    };
    if (with_colour) {
      if (source.color_compressed) {
        instantiate(messages.color, color_where, &color_packed);
      } else {
        instantiate(messages.color, color_where, &color_raw);
      }
    }
    if (source.depth_compressed) {
      instantiate(messages.depth, depth_where, &depth_packed);
    } else {
      instantiate(messages.depth, depth_where, &depth_raw);
    }
  }
  const int width = calib_.camera.camera.width();
  const int height = calib_.camera.camera.height();
  auto checkSize = [&](const cv::Mat& image, const std::string& where) {
    if (image.cols != width || image.rows != height) {
      throw InputError(where + ": size " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                       " differs from the calibrated image size " + std::to_string(width) + "x" +
                       std::to_string(height) + " (" + source.calib_source + ")");
    }
  };
  if (with_colour) {
    detail::ColorConversion conversion = detail::ColorConversion::kNone;
    frame->color_bgr = source.color_compressed ? detail::decodeCompressedColor(*color_packed, color_where, &conversion)
                                               : detail::decodeColorImage(*color_raw, color_where, &conversion);
    if (conversion != detail::ColorConversion::kNone && !source.warned_conversion.exchange(true)) {
      log::warn(color_where, ": ", conversion == detail::ColorConversion::kFromGrey ? "8-bit grey" : "8-bit with alpha",
                " colour image converted to 3-channel BGR (warned once per bag)");
    }
    checkSize(frame->color_bgr, color_where);
  }
  frame->depth_m = source.depth_compressed ? detail::decodeCompressedDepth(*depth_packed, depth_where)
                                           : detail::decodeDepthImage(*depth_raw, depth_where);
  checkSize(frame->depth_m, depth_where);
}

BagTopics bagTopicPreset(const std::string& name) {
  BagTopics topics;
  if (name == "tum") {
    topics.rgb = "/camera/rgb/image_color";
    topics.depth = "/camera/depth/image";
    topics.camera_info = "/camera/rgb/camera_info";
  } else if (name == "realsense" || name == "realsense-unite") {
    topics.rgb = "/camera/color/image_raw";
    topics.depth = "/camera/aligned_depth_to_color/image_raw";
    topics.camera_info = "/camera/color/camera_info";
    if (name == "realsense") {
      topics.accel = "/camera/accel/sample";
      topics.gyro = "/camera/gyro/sample";
    } else {
      topics.imu = "/camera/imu";
    }
  } else if (name == "openloris") {
    topics.rgb = "/d400/color/image_raw";
    topics.depth = "/d400/aligned_depth_to_color/image_raw";
    topics.camera_info = "/d400/color/camera_info";
    topics.accel = "/d400/accel/sample";
    topics.gyro = "/d400/gyro/sample";
  } else {
    throw InputError("--bag-preset " + name + ": unknown preset (expected " + bagTopicPresetNames() + ")");
  }
  return topics;
}

std::string bagTopicPresetNames() { return "tum, realsense, realsense-unite, openloris"; }

std::vector<BagTopicInfo> listBagTopics(const std::string& bag_path) {
  rosbag::Bag bag;
  openBagFile(bag, bag_path);
  return topicTable(bag);
}

std::string formatBagTopics(const std::vector<BagTopicInfo>& topics) {
  size_t topic_width = 5, type_width = 4;
  for (const BagTopicInfo& info : topics) {
    topic_width = std::max(topic_width, info.topic.size());
    type_width = std::max(type_width, info.type.size());
  }
  std::ostringstream os;
  os << std::left << std::setw(static_cast<int>(topic_width)) << "topic" << "  " << std::setw(static_cast<int>(type_width))
     << "type" << "  " << std::right << std::setw(8) << "count" << "  " << std::setw(9) << "rate_hz" << "\n";
  for (const BagTopicInfo& info : topics) {
    os << std::left << std::setw(static_cast<int>(topic_width)) << info.topic << "  "
       << std::setw(static_cast<int>(type_width)) << info.type << "  " << std::right << std::setw(8) << info.count
       << "  " << std::setw(9) << std::fixed << std::setprecision(2) << info.rate_hz << "\n";
  }
  return os.str();
}

bool bagSupportCompiled() { return true; }

}  // namespace ltlo::io
