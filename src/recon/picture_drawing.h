#pragma once
// 2-D drawing for the snapshots: labels, legends, the frame overlays and the contact sheet.
#include <opencv2/core/mat.hpp>
#include <string>
#include <utility>
#include <vector>

#include "ltlo/recon/snapshots.h"

namespace ltlo::recon {

/// A labelled picture for the contact sheet.
struct Tile {
  std::string label;
  cv::Mat image;  ///< CV_8UC3
};

/// White text on a dark band at the top-left corner.
void drawLabel(cv::Mat* image, const std::string& text);
/// Coloured line samples with their names, top-right.
void drawLegend(cv::Mat* image, const std::vector<std::pair<std::string, cv::Scalar>>& entries);
/// Input RGB | overlay (dynamic pixels red, pixels without depth dimmed), half size, labelled.
cv::Mat overlayRow(const OverlayFrame& frame);
/// Tiles scaled to `tile_width` (letterboxed to 4:3), `columns` per row, a title band on top.
cv::Mat contactSheet(const std::vector<Tile>& tiles, const std::string& title, int columns,
                     int tile_width);

}  // namespace ltlo::recon
