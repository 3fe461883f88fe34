#include "picture_drawing.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace ltlo::recon {
namespace {

const cv::Scalar kTextBgr(240, 240, 240);
const cv::Scalar kBandBgr(20, 20, 20);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

void textWithBand(cv::Mat* image, const std::string& text, cv::Point origin, double scale) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, kFont, scale, 1, &baseline);
  cv::rectangle(*image, origin + cv::Point(-4, -size.height - 4),
                origin + cv::Point(size.width + 4, baseline + 2), kBandBgr, cv::FILLED);
  cv::putText(*image, text, origin, kFont, scale, kTextBgr, 1, cv::LINE_AA);
}

}  // namespace

void drawLabel(cv::Mat* image, const std::string& text) {
  textWithBand(image, text, cv::Point(8, 22), 0.55);
}

void drawLegend(cv::Mat* image, const std::vector<std::pair<std::string, cv::Scalar>>& entries) {
  int y = 22;
  for (const auto& [name, colour] : entries) {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(name, kFont, 0.5, 1, &baseline);
    const int x = image->cols - size.width - 48;
    cv::rectangle(*image, cv::Point(x - 36, y - size.height - 4),
                  cv::Point(image->cols - 4, y + baseline + 2), kBandBgr, cv::FILLED);
    cv::line(*image, cv::Point(x - 30, y - 5), cv::Point(x - 6, y - 5), colour, 3, cv::LINE_AA);
    cv::putText(*image, name, cv::Point(x, y), kFont, 0.5, kTextBgr, 1, cv::LINE_AA);
    y += size.height + 12;
  }
}

cv::Mat overlayRow(const OverlayFrame& frame) {
  const cv::Mat& rgb = frame.colour_bgr;
  cv::Mat overlay = rgb.clone();
  long dynamic = 0;
  for (int v = 0; v < rgb.rows; ++v) {
    cv::Vec3b* out = overlay.ptr<cv::Vec3b>(v);
    const float* depth = frame.depth_m.empty() ? nullptr : frame.depth_m.ptr<float>(v);
    const uint8_t* mask = frame.dynamic_mask.empty() ? nullptr : frame.dynamic_mask.ptr<uint8_t>(v);
    for (int u = 0; u < rgb.cols; ++u) {
      cv::Vec3b& p = out[u];
      if (mask != nullptr && mask[u] != 0) {
        ++dynamic;
        p = cv::Vec3b(static_cast<uint8_t>(0.4 * p[0]), static_cast<uint8_t>(0.4 * p[1]),
                      static_cast<uint8_t>(0.4 * p[2] + 0.6 * 255));
      } else if (depth != nullptr && !(depth[u] > 0.0f)) {
        p = cv::Vec3b(static_cast<uint8_t>(0.25 * p[0]), static_cast<uint8_t>(0.25 * p[1]),
                      static_cast<uint8_t>(0.25 * p[2]));
      }
    }
  }
  cv::Mat row;
  cv::hconcat(rgb, overlay, row);
  cv::resize(row, row, cv::Size(row.cols / 2, row.rows / 2), 0, 0, cv::INTER_AREA);
  textWithBand(&row, cv::format("frame %d, t = %.2f s: input RGB", frame.index, frame.t_s),
               cv::Point(6, 18), 0.45);
  const std::string right = frame.dynamic_mask.empty()
                                ? std::string("no segmentation: every pixel fused")
                                : cv::format("dynamic (red) %.1f %%, no depth dark",
                                             100.0 * dynamic / std::max(1, rgb.rows * rgb.cols));
  textWithBand(&row, right, cv::Point(row.cols / 2 + 6, 18), 0.45);
  return row;
}

cv::Mat contactSheet(const std::vector<Tile>& tiles, const std::string& title, int columns,
                     int tile_width) {
  const int tile_height = tile_width * 3 / 4;
  const int label_height = 20;
  const int title_height = 34;
  const int rows = (static_cast<int>(tiles.size()) + columns - 1) / columns;
  cv::Mat sheet(title_height + rows * (tile_height + label_height), columns * tile_width, CV_8UC3,
                cv::Scalar(32, 32, 32));
  cv::putText(sheet, title, cv::Point(8, 23), kFont, 0.6, kTextBgr, 1, cv::LINE_AA);
  for (std::size_t k = 0; k < tiles.size(); ++k) {
    const int x0 = static_cast<int>(k % columns) * tile_width;
    const int y0 = title_height + static_cast<int>(k / columns) * (tile_height + label_height);
    const cv::Mat& image = tiles[k].image;
    const double scale = std::min(static_cast<double>(tile_width) / image.cols,
                                  static_cast<double>(tile_height) / image.rows);
    cv::Mat scaled;
    cv::resize(image, scaled,
               cv::Size(std::max(1, static_cast<int>(image.cols * scale)),
                        std::max(1, static_cast<int>(image.rows * scale))),
               0, 0, cv::INTER_AREA);
    const int dx = (tile_width - scaled.cols) / 2, dy = (tile_height - scaled.rows) / 2;
    scaled.copyTo(sheet(cv::Rect(x0 + dx, y0 + dy, scaled.cols, scaled.rows)));
    cv::putText(sheet, tiles[k].label, cv::Point(x0 + 6, y0 + tile_height + 15), kFont, 0.45,
                kTextBgr, 1, cv::LINE_AA);
  }
  return sheet;
}

}  // namespace ltlo::recon
