#include "bag_messages.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "ltlo/core/errors.h"
#include "png_decode.h"

namespace ltlo::io::detail {
namespace {

bool hostIsBigEndian() {
  const uint16_t probe = 1;
  uint8_t first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 0;
}

// The message's pixels as a Mat header over its data (no copy), after the layout checks: at least
// `channels` x `bytes_per_channel` per pixel in a row of `step` bytes, and height rows of data.
cv::Mat wrapPixels(const sensor_msgs::Image& message, int cv_type, const std::string& where) {
  const std::size_t pixel_bytes = CV_ELEM_SIZE(cv_type);
  if (message.width == 0 || message.height == 0) {
    throw InputError(where + ": empty image (" + std::to_string(message.width) + "x" +
                     std::to_string(message.height) + ")");
  }
  if (message.step < message.width * pixel_bytes) {
    throw InputError(where + ": row step " + std::to_string(message.step) + " bytes is less than width " +
                     std::to_string(message.width) + " x " + std::to_string(pixel_bytes) + " bytes of " +
                     message.encoding);
  }
  const std::size_t needed = static_cast<std::size_t>(message.step) * message.height;
  if (message.data.size() < needed) {
    throw InputError(where + ": " + std::to_string(message.data.size()) + " bytes of data, " +
                     std::to_string(message.width) + "x" + std::to_string(message.height) + " " +
                     message.encoding + " with step " + std::to_string(message.step) + " needs " +
                     std::to_string(needed));
  }
  return cv::Mat(static_cast<int>(message.height), static_cast<int>(message.width), cv_type,
                 const_cast<uint8_t*>(message.data.data()), message.step);
}

// BGR from a decoded 1-, 3- or 4-channel 8-bit image (grey and BGRA as the folder reader converts).
cv::Mat toBgr(const cv::Mat& image, bool rgb_order, ColorConversion* conversion) {
  *conversion = ColorConversion::kNone;
  cv::Mat bgr;
  switch (image.channels()) {
    case 1:
      *conversion = ColorConversion::kFromGrey;
      cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
      break;
    case 3:
      if (rgb_order) {
        cv::cvtColor(image, bgr, cv::COLOR_RGB2BGR);
      } else {
        bgr = image.clone();
      }
      break;
    default:
      *conversion = ColorConversion::kFromAlpha;
      cv::cvtColor(image, bgr, rgb_order ? cv::COLOR_RGBA2BGR : cv::COLOR_BGRA2BGR);
      break;
  }
  return bgr;
}

// Image bytes of a compressed message: our PNG fast path first (the folder reader's decoder, so
// PNG frames are identical to the files), then OpenCV for JPEG and the rest.
cv::Mat decodeBytes(const uint8_t* data, std::size_t size, const std::string& where) {
  cv::Mat image;
  if (decodePngFast(data, size, &image)) return image;
  try {
    const cv::Mat buffer(1, static_cast<int>(size), CV_8UC1, const_cast<uint8_t*>(data));
    image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw InputError(where + ": cannot decode the compressed image (" + e.msg + ")");
  }
  if (image.empty()) {
    throw InputError(where + ": cannot decode the compressed image (" + std::to_string(size) + " bytes)");
  }
  return image;
}

std::string trim(const std::string& text) {
  const std::size_t begin = text.find_first_not_of(" \t");
  if (begin == std::string::npos) return "";
  return text.substr(begin, text.find_last_not_of(" \t") - begin + 1);
}

}  // namespace

double stampSeconds(uint32_t sec, uint32_t nsec) {
  char text[32];
  std::snprintf(text, sizeof(text), "%u.%09u", sec, nsec);
  return std::strtod(text, nullptr);
}

cv::Mat decodeColorImage(const sensor_msgs::Image& message, const std::string& where,
                         ColorConversion* conversion) {
  const std::string& encoding = message.encoding;
  if (encoding == "rgb8" || encoding == "bgr8") {
    return toBgr(wrapPixels(message, CV_8UC3, where), encoding == "rgb8", conversion);
  }
  if (encoding == "mono8" || encoding == "8UC1") {
    return toBgr(wrapPixels(message, CV_8UC1, where), false, conversion);
  }
  if (encoding == "rgba8" || encoding == "bgra8") {
    return toBgr(wrapPixels(message, CV_8UC4, where), encoding == "rgba8", conversion);
  }
  throw InputError(where + ": unsupported colour encoding '" + encoding +
                   "' (expected rgb8, bgr8, mono8, rgba8 or bgra8)");
}

cv::Mat decodeDepthImage(const sensor_msgs::Image& message, const std::string& where) {
  const std::string& encoding = message.encoding;
  const bool swap_bytes = (message.is_bigendian != 0) != hostIsBigEndian();
  cv::Mat depth_m;
  if (encoding == "16UC1" || encoding == "mono16") {
    cv::Mat raw = wrapPixels(message, CV_16UC1, where);
    if (swap_bytes) {
      raw = raw.clone();
      for (int v = 0; v < raw.rows; ++v) {
        uint16_t* row = raw.ptr<uint16_t>(v);
        for (int u = 0; u < raw.cols; ++u) row[u] = static_cast<uint16_t>((row[u] >> 8) | (row[u] << 8));
      }
    }
    // Millimetres (REP 118), converted as the folder reader converts DepthMapFactor 1000.
    raw.convertTo(depth_m, CV_32F, 1.0 / 1000.0);
    return depth_m;
  }
  if (encoding == "32FC1") {
    wrapPixels(message, CV_32FC1, where).copyTo(depth_m);
    for (int v = 0; v < depth_m.rows; ++v) {
      float* row = depth_m.ptr<float>(v);
      for (int u = 0; u < depth_m.cols; ++u) {
        float value = row[u];
        if (swap_bytes) {
          uint32_t bits = 0;
          std::memcpy(&bits, &value, 4);
          bits = __builtin_bswap32(bits);
          std::memcpy(&value, &bits, 4);
        }
        row[u] = std::isfinite(value) && value > 0.0f ? value : 0.0f;  // NaN = no reading (TUM bags)
      }
    }
    return depth_m;
  }
  throw InputError(where + ": unsupported depth encoding '" + encoding +
                   "' (expected 16UC1 or mono16 in millimetres, or 32FC1 in metres)");
}

cv::Mat decodeCompressedColor(const sensor_msgs::CompressedImage& message, const std::string& where,
                              ColorConversion* conversion) {
  const std::string& format = message.format;
  if (format.find("compressedDepth") != std::string::npos) {
    throw InputError(where + ": colour topic holds compressed depth (format '" + format + "')");
  }
  const bool known = format.find("jpeg") != std::string::npos || format.find("jpg") != std::string::npos ||
                     format.find("png") != std::string::npos;
  if (!known) {
    throw InputError(where + ": unsupported compressed colour format '" + format + "' (expected jpeg or png)");
  }
  // image_transport encodes colour as BGR before compressing; the decoded image is BGR.
  return toBgr(decodeBytes(message.data.data(), message.data.size(), where), false, conversion);
}

CompressedDepthHeader parseCompressedDepthHeader(const uint8_t* data, std::size_t size,
                                                 const std::string& where) {
  if (size <= kCompressedDepthHeaderBytes) {
    throw InputError(where + ": compressedDepth data of " + std::to_string(size) +
                     " bytes is too short for its 12-byte header and an image");
  }
  CompressedDepthHeader header;
  std::memcpy(&header.format, data, 4);
  std::memcpy(&header.quant_a, data + 4, 4);
  std::memcpy(&header.quant_b, data + 8, 4);
  return header;
}

cv::Mat decodeCompressedDepth(const sensor_msgs::CompressedImage& message, const std::string& where) {
  const std::string& format = message.format;
  const std::size_t separator = format.find(';');
  const std::string encoding = trim(format.substr(0, separator));
  const std::string method = separator == std::string::npos ? "" : trim(format.substr(separator + 1));
  if (method != "compressedDepth" && method != "compressedDepth png") {
    throw InputError(where + ": unsupported depth format '" + format +
                     "' (expected '16UC1; compressedDepth' or '32FC1; compressedDepth', PNG inside)");
  }
  const CompressedDepthHeader header =
      parseCompressedDepthHeader(message.data.data(), message.data.size(), where);
  const cv::Mat image = decodeBytes(message.data.data() + kCompressedDepthHeaderBytes,
                                    message.data.size() - kCompressedDepthHeaderBytes, where);
  if (image.type() != CV_16UC1) {
    throw InputError(where + ": compressedDepth image is not 16-bit 1-channel (" +
                     std::to_string(image.channels()) + " channel(s) of " +
                     std::to_string(image.elemSize1() * 8) + "-bit)");
  }
  cv::Mat depth_m;
  if (encoding == "16UC1" || encoding == "mono16") {
    image.convertTo(depth_m, CV_32F, 1.0 / 1000.0);
    return depth_m;
  }
  if (encoding == "32FC1") {
    if (header.format != 0 || !std::isfinite(header.quant_a) || !std::isfinite(header.quant_b)) {
      std::ostringstream os;
      os << where << ": compressedDepth header format " << header.format << ", quantisation "
         << header.quant_a << ", " << header.quant_b << " (expected format 0, inverse depth)";
      throw InputError(os.str());
    }
    depth_m.create(image.rows, image.cols, CV_32F);
    for (int v = 0; v < image.rows; ++v) {
      const uint16_t* in = image.ptr<uint16_t>(v);
      float* out = depth_m.ptr<float>(v);
      for (int u = 0; u < image.cols; ++u) {
        const float depth = in[u] == 0 ? 0.0f : header.quant_a / (static_cast<float>(in[u]) - header.quant_b);
        out[u] = std::isfinite(depth) && depth > 0.0f ? depth : 0.0f;
      }
    }
    return depth_m;
  }
  throw InputError(where + ": unsupported compressedDepth encoding '" + encoding + "' (expected 16UC1 or 32FC1)");
}

CameraCalib cameraCalibFromInfo(const sensor_msgs::CameraInfo& info, const std::string& where) {
  const double fx = info.K[0], fy = info.K[4], cx = info.K[2], cy = info.K[5];
  if (info.width == 0 || info.height == 0 || !(fx > 0.0) || !(fy > 0.0) || !std::isfinite(cx) ||
      !std::isfinite(cy)) {
    std::ostringstream os;
    os << where << ": CameraInfo without a usable calibration (" << info.width << "x" << info.height
       << ", fx=" << fx << " fy=" << fy << " cx=" << cx << " cy=" << cy << ")";
    throw InputError(os.str());
  }
  CameraCalib camera;
  camera.camera = PinholeCamera(fx, fy, cx, cy, static_cast<int>(info.width), static_cast<int>(info.height));
  const std::vector<double>& d = info.D;
  auto coefficient = [&d](std::size_t i) { return i < d.size() ? d[i] : 0.0; };
  bool all_zero = true;
  for (double value : d) all_zero = all_zero && value == 0.0;
  const std::string& model = info.distortion_model;
  LensDistortion& lens = camera.lens;
  if (all_zero) {
    lens.model = LensModel::kPinhole;
  } else if (model == "plumb_bob" || model == "radtan") {
    lens.model = LensModel::kRadTan;
    lens.k1 = coefficient(0), lens.k2 = coefficient(1), lens.p1 = coefficient(2), lens.p2 = coefficient(3);
    lens.k3 = coefficient(4);
  } else if (model == "rational_polynomial") {
    lens.model = LensModel::kRational;
    lens.k1 = coefficient(0), lens.k2 = coefficient(1), lens.p1 = coefficient(2), lens.p2 = coefficient(3);
    lens.k3 = coefficient(4), lens.k4 = coefficient(5), lens.k5 = coefficient(6), lens.k6 = coefficient(7);
  } else if (model == "equidistant") {
    lens.model = LensModel::kKannalaBrandt;
    lens.k1 = coefficient(0), lens.k2 = coefficient(1), lens.k3 = coefficient(2), lens.k4 = coefficient(3);
  } else {
    throw InputError(where + ": unsupported CameraInfo distortion_model '" + model +
                     "' (expected plumb_bob, rational_polynomial or equidistant)");
  }
  for (double value : d) {
    if (!std::isfinite(value)) throw InputError(where + ": CameraInfo distortion coefficient is not finite");
  }
  return camera;
}

std::string describeCamera(const CameraCalib& camera) {
  std::ostringstream os;
  os.precision(10);
  const PinholeCamera& k = camera.camera;
  os << k.width() << "x" << k.height() << " fx=" << k.fx() << " fy=" << k.fy() << " cx=" << k.cx()
     << " cy=" << k.cy() << " " << camera.lens.describe();
  return os.str();
}

bool sameCamera(const CameraCalib& a, const CameraCalib& b) {
  const PinholeCamera& ka = a.camera;
  const PinholeCamera& kb = b.camera;
  auto near = [](double x, double y, double tolerance) { return std::abs(x - y) <= tolerance; };
  const LensDistortion& la = a.lens;
  const LensDistortion& lb = b.lens;
  const bool same_lens = (la.isDistorted() == lb.isDistorted()) &&
                         (!la.isDistorted() ||
                          (la.model == lb.model && near(la.k1, lb.k1, 1e-9) && near(la.k2, lb.k2, 1e-9) &&
                           near(la.k3, lb.k3, 1e-9) && near(la.k4, lb.k4, 1e-9) && near(la.k5, lb.k5, 1e-9) &&
                           near(la.k6, lb.k6, 1e-9) && near(la.p1, lb.p1, 1e-9) && near(la.p2, lb.p2, 1e-9)));
  return ka.width() == kb.width() && ka.height() == kb.height() && near(ka.fx(), kb.fx(), 1e-6) &&
         near(ka.fy(), kb.fy(), 1e-6) && near(ka.cx(), kb.cx(), 1e-6) && near(ka.cy(), kb.cy(), 1e-6) &&
         same_lens;
}

}  // namespace ltlo::io::detail
