#pragma once
// sensor_msgs messages of a ROS 1 bag into our image and calibration types (private to ltlo_io;
// bag_reader.cc reads the messages, the io tests call these on messages they build). `where`
// names the message in errors ("seq.bag: topic /camera/depth/image message 12"); every failure
// throws InputError "<where>: <what> (<value>)".
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

#include "ltlo/core/calib.h"

namespace ltlo::io::detail {

/// Header stamp as seconds, bit-identical to parsing its decimal text "<sec>.<nsec, 9 digits>"
/// (what the folder reader does with the same instant written to a text index): a sequence
/// converted between the two layouts keeps the very same doubles.
double stampSeconds(uint32_t sec, uint32_t nsec);

/// How a colour message was delivered, for the reader's warn-once line.
enum class ColorConversion { kNone, kFromGrey, kFromAlpha };

/// sensor_msgs/Image colour (rgb8, bgr8, mono8, rgba8, bgra8) as CV_8UC3 BGR.
cv::Mat decodeColorImage(const sensor_msgs::Image& message, const std::string& where,
                         ColorConversion* conversion);
/// sensor_msgs/Image depth (16UC1 / mono16 in millimetres, 32FC1 in metres) as CV_32F metres,
/// 0 = no reading (NaN, infinite and non-positive values of 32FC1 become 0).
cv::Mat decodeDepthImage(const sensor_msgs::Image& message, const std::string& where);
/// sensor_msgs/CompressedImage colour (format "jpeg", "png", or image_transport's
/// "<encoding>; jpeg compressed bgr8") as CV_8UC3 BGR.
cv::Mat decodeCompressedColor(const sensor_msgs::CompressedImage& message, const std::string& where,
                              ColorConversion* conversion);

/// The 12-byte header image_transport's compressedDepth plugin writes before the PNG: the format
/// (0 = inverse depth) and the two quantisation parameters of 32FC1 depth.
struct CompressedDepthHeader {
  int32_t format = 0;
  float quant_a = 0.0f;  ///< depth_m = quant_a / (value - quant_b) for 32FC1 (value 0 = none)
  float quant_b = 0.0f;
};
constexpr std::size_t kCompressedDepthHeaderBytes = 12;
CompressedDepthHeader parseCompressedDepthHeader(const uint8_t* data, std::size_t size,
                                                 const std::string& where);
/// sensor_msgs/CompressedImage "16UC1; compressedDepth [png]" (millimetres) or
/// "32FC1; compressedDepth [png]" (quantised inverse depth) as CV_32F metres, 0 = no reading.
cv::Mat decodeCompressedDepth(const sensor_msgs::CompressedImage& message, const std::string& where);

/// Size, K and distortion of a CameraInfo ("plumb_bob"/"radtan" -> radtan, "rational_polynomial"
/// -> rational, "equidistant" -> Kannala-Brandt; all-zero coefficients -> no lens). fps and
/// DepthMapFactor keep their defaults (16UC1 depth is millimetres by REP 118: factor 1000).
CameraCalib cameraCalibFromInfo(const sensor_msgs::CameraInfo& info, const std::string& where);

/// "640x480 fx=525 fy=525 cx=319.5 cy=239.5 radtan k1=..." for the conflict warning.
std::string describeCamera(const CameraCalib& camera);
/// True when size, intrinsics (to 1e-6 px) and lens coefficients (to 1e-9) agree.
bool sameCamera(const CameraCalib& a, const CameraCalib& b);

}  // namespace ltlo::io::detail
