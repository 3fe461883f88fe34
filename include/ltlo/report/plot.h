#pragma once
/// Plots drawn with OpenCV (no Python, no plotting library): a line/area plot with axes, ticks,
/// labels and a legend, and a horizontal bar chart. Colours are BGR.
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

namespace ltlo::report {

/// Ticks at 1, 2 or 5 times a power of ten, about `target` of them across [lo, hi].
std::vector<double> niceTicks(double lo, double hi, int target = 6);

class Plot {
 public:
  Plot(int width, int height, const std::string& title);

  /// Data ranges and axis labels; with equal_aspect one metre is as long on both axes (the
  /// ranges grow to fill the panel).
  void setAxes(double x0, double x1, double y0, double y1, const std::string& x_label,
               const std::string& y_label, bool equal_aspect = false);
  /// A vertical band over [x0, x1] behind the data.
  void shadeX(double x0, double x1, const cv::Scalar& colour);
  /// A polyline; NaN in either coordinate breaks it.
  void line(const std::vector<double>& xs, const std::vector<double>& ys, const cv::Scalar& colour,
            int width_px = 2);
  void marker(double x, double y, const cv::Scalar& colour, int radius_px = 5);
  /// A message in the middle of the panel (e.g. "no data").
  void note(const std::string& text);
  void addLegend(const std::string& name, const cv::Scalar& colour);
  /// The picture with axes, ticks, labels and legend drawn over the data.
  cv::Mat render() const;

 private:
  cv::Point toPixel(double x, double y) const;

  cv::Mat canvas_;
  std::string title_;
  std::string x_label_, y_label_;
  double x0_ = 0, x1_ = 1, y0_ = 0, y1_ = 1;
  cv::Rect area_;  // the data area in pixels
  std::vector<std::pair<std::string, cv::Scalar>> legend_;
  std::string note_;
};

/// One series of a bar chart: a value per label (NaN = no bar).
struct BarSeries {
  std::string name;
  cv::Scalar colour;
  std::vector<double> values;
};

/// Horizontal bars, one group per label, one bar per series; values in `unit`.
cv::Mat barChart(int width, int height, const std::string& title, const std::string& unit,
                 const std::vector<std::string>& labels, const std::vector<BarSeries>& series);

/// Panels side by side and rows stacked (each row as wide as the widest; grey padding).
cv::Mat grid(const std::vector<std::vector<cv::Mat>>& rows);

}  // namespace ltlo::report
