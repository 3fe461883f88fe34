#include "ltlo/report/plot.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace ltlo::report {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kGridGrey(225, 225, 225);
// Margins of the data area: left (tick labels), right, top (title), bottom (ticks and label).
constexpr int kLeft = 70, kRight = 20, kTop = 36, kBottom = 48;

std::string tickText(double value, double step) {
  const int decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
  return cv::format("%.*f", decimals, std::abs(value) < 1e-12 ? 0.0 : value);
}

}  // namespace

std::vector<double> niceTicks(double lo, double hi, int target) {
  std::vector<double> ticks;
  if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return ticks;
  const double raw = (hi - lo) / std::max(1, target);
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  double step = power;
  for (double f : {1.0, 2.0, 5.0, 10.0}) {
    step = f * power;
    if (step >= raw) break;
  }
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * step; t += step) ticks.push_back(t);
  return ticks;
}

Plot::Plot(int width, int height, const std::string& title)
    : canvas_(height, width, CV_8UC3, kWhite),
      title_(title),
      area_(kLeft, kTop, width - kLeft - kRight, height - kTop - kBottom) {}

void Plot::setAxes(double x0, double x1, double y0, double y1, const std::string& x_label,
                   const std::string& y_label, bool equal_aspect) {
  if (!(x1 > x0)) x1 = x0 + 1.0;
  if (!(y1 > y0)) y1 = y0 + 1.0;
  if (equal_aspect) {
    const double scale = std::max((x1 - x0) / area_.width, (y1 - y0) / area_.height);
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    x0 = cx - 0.5 * scale * area_.width;
    x1 = cx + 0.5 * scale * area_.width;
    y0 = cy - 0.5 * scale * area_.height;
    y1 = cy + 0.5 * scale * area_.height;
  }
  x0_ = x0;
  x1_ = x1;
  y0_ = y0;
  y1_ = y1;
  x_label_ = x_label;
  y_label_ = y_label;
  for (double t : niceTicks(x0_, x1_)) {
    const int u = toPixel(t, y0_).x;
    cv::line(canvas_, cv::Point(u, area_.y), cv::Point(u, area_.y + area_.height), kGridGrey, 1);
  }
  for (double t : niceTicks(y0_, y1_)) {
    const int v = toPixel(x0_, t).y;
    cv::line(canvas_, cv::Point(area_.x, v), cv::Point(area_.x + area_.width, v), kGridGrey, 1);
  }
}

cv::Point Plot::toPixel(double x, double y) const {
  const double u = area_.x + (x - x0_) / (x1_ - x0_) * area_.width;
  const double v = area_.y + area_.height - (y - y0_) / (y1_ - y0_) * area_.height;
  return cv::Point(static_cast<int>(std::lround(u)), static_cast<int>(std::lround(v)));
}

void Plot::shadeX(double x0, double x1, const cv::Scalar& colour) {
  const int u0 = std::clamp(toPixel(x0, y0_).x, area_.x, area_.x + area_.width);
  const int u1 = std::clamp(toPixel(x1, y0_).x, area_.x, area_.x + area_.width);
  if (u1 <= u0) return;
  cv::rectangle(canvas_, cv::Point(u0, area_.y), cv::Point(u1, area_.y + area_.height), colour,
                cv::FILLED);
}

void Plot::line(const std::vector<double>& xs, const std::vector<double>& ys,
                const cv::Scalar& colour, int width_px) {
  std::vector<cv::Point> points;
  cv::Mat clipped = canvas_(area_);
  auto flush = [&] {
    if (points.size() > 1) cv::polylines(clipped, points, false, colour, width_px, cv::LINE_AA);
    points.clear();
  };
  for (std::size_t i = 0; i < xs.size() && i < ys.size(); ++i) {
    if (!std::isfinite(xs[i]) || !std::isfinite(ys[i])) {
      flush();
      continue;
    }
    points.push_back(toPixel(xs[i], ys[i]) - area_.tl());
  }
  flush();
}

void Plot::marker(double x, double y, const cv::Scalar& colour, int radius_px) {
  cv::circle(canvas_, toPixel(x, y), radius_px, colour, 2, cv::LINE_AA);
}

void Plot::note(const std::string& text) { note_ = text; }

void Plot::addLegend(const std::string& name, const cv::Scalar& colour) {
  legend_.emplace_back(name, colour);
}

cv::Mat Plot::render() const {
  cv::Mat out = canvas_.clone();
  cv::rectangle(out, area_, kInk, 1);
  cv::putText(out, title_, cv::Point(kLeft, 24), kFont, 0.6, kInk, 1, cv::LINE_AA);
  const std::vector<double> x_ticks = niceTicks(x0_, x1_);
  const double x_step = x_ticks.size() > 1 ? x_ticks[1] - x_ticks[0] : 1.0;
  for (double t : x_ticks) {
    const cv::Point p = toPixel(t, y0_);
    cv::line(out, p, p + cv::Point(0, 5), kInk, 1);
    const std::string label = tickText(t, x_step);
    int base = 0;
    const cv::Size size = cv::getTextSize(label, kFont, 0.4, 1, &base);
    cv::putText(out, label, p + cv::Point(-size.width / 2, 18), kFont, 0.4, kInk, 1, cv::LINE_AA);
  }
  const std::vector<double> y_ticks = niceTicks(y0_, y1_);
  const double y_step = y_ticks.size() > 1 ? y_ticks[1] - y_ticks[0] : 1.0;
  for (double t : y_ticks) {
    const cv::Point p = toPixel(x0_, t);
    cv::line(out, p, p - cv::Point(5, 0), kInk, 1);
    const std::string label = tickText(t, y_step);
    int base = 0;
    const cv::Size size = cv::getTextSize(label, kFont, 0.4, 1, &base);
    cv::putText(out, label, p + cv::Point(-size.width - 8, 4), kFont, 0.4, kInk, 1, cv::LINE_AA);
  }
  int base = 0;
  const cv::Size x_size = cv::getTextSize(x_label_, kFont, 0.45, 1, &base);
  cv::putText(out, x_label_, cv::Point(area_.x + area_.width / 2 - x_size.width / 2, out.rows - 10),
              kFont, 0.45, kInk, 1, cv::LINE_AA);
  // The y label rotated: drawn into a strip and turned.
  const cv::Size y_size = cv::getTextSize(y_label_, kFont, 0.45, 1, &base);
  cv::Mat strip(y_size.height + 8, y_size.width + 4, CV_8UC3, kWhite);
  cv::putText(strip, y_label_, cv::Point(2, y_size.height + 2), kFont, 0.45, kInk, 1, cv::LINE_AA);
  cv::rotate(strip, strip, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int y_top = std::max(0, area_.y + area_.height / 2 - strip.rows / 2);
  if (strip.rows <= out.rows - y_top && strip.cols < kLeft) {
    strip.copyTo(out(cv::Rect(4, y_top, strip.cols, strip.rows)));
  }
  int y = area_.y + 18;
  for (const auto& [name, colour] : legend_) {
    const cv::Size size = cv::getTextSize(name, kFont, 0.45, 1, &base);
    const int x = area_.x + area_.width - size.width - 40;
    cv::rectangle(out, cv::Point(x - 34, y - 14), cv::Point(area_.x + area_.width - 4, y + 6),
                  kWhite, cv::FILLED);
    cv::line(out, cv::Point(x - 28, y - 4), cv::Point(x - 6, y - 4), colour, 3, cv::LINE_AA);
    cv::putText(out, name, cv::Point(x, y), kFont, 0.45, kInk, 1, cv::LINE_AA);
    y += 22;
  }
  if (!note_.empty()) {
    const cv::Size size = cv::getTextSize(note_, kFont, 0.55, 1, &base);
    cv::putText(out, note_,
                cv::Point(area_.x + area_.width / 2 - size.width / 2, area_.y + area_.height / 2),
                kFont, 0.55, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
  }
  return out;
}

cv::Mat barChart(int width, int height, const std::string& title, const std::string& unit,
                 const std::vector<std::string>& labels, const std::vector<BarSeries>& series) {
  cv::Mat out(height, width, CV_8UC3, kWhite);
  cv::putText(out, title, cv::Point(12, 24), kFont, 0.6, kInk, 1, cv::LINE_AA);
  if (labels.empty() || series.empty()) {
    cv::putText(out, "no timing in metrics.json", cv::Point(width / 3, height / 2), kFont, 0.55,
                cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
    return out;
  }
  int label_width = 0, base = 0;
  for (const std::string& label : labels) {
    label_width = std::max(label_width, cv::getTextSize(label, kFont, 0.42, 1, &base).width);
  }
  const int left = label_width + 20, right = 80, top = 40 + 22 * static_cast<int>(series.size());
  const int bottom = 30;
  double max_value = 0.0;
  for (const BarSeries& s : series) {
    for (double v : s.values) {
      if (std::isfinite(v)) max_value = std::max(max_value, v);
    }
  }
  if (!(max_value > 0.0)) max_value = 1.0;
  const double group = static_cast<double>(height - top - bottom) / labels.size();
  const double bar = std::max(2.0, 0.8 * group / series.size());
  const int plot_width = width - left - right;
  for (double t : niceTicks(0.0, max_value)) {
    const int u = left + static_cast<int>(t / max_value * plot_width);
    cv::line(out, cv::Point(u, top - 4), cv::Point(u, height - bottom), kGridGrey, 1);
    cv::putText(out, cv::format("%g", t), cv::Point(u - 8, height - bottom + 16), kFont, 0.38, kInk,
                1, cv::LINE_AA);
  }
  cv::putText(out, unit, cv::Point(width - right + 8, height - bottom + 16), kFont, 0.4, kInk, 1,
              cv::LINE_AA);
  for (std::size_t l = 0; l < labels.size(); ++l) {
    const int y0 = top + static_cast<int>(l * group);
    cv::putText(out, labels[l], cv::Point(8, y0 + static_cast<int>(group / 2) + 4), kFont, 0.42,
                kInk, 1, cv::LINE_AA);
    for (std::size_t s = 0; s < series.size(); ++s) {
      const double v = l < series[s].values.size() ? series[s].values[l] : NAN;
      if (!std::isfinite(v)) continue;
      const int y = y0 + static_cast<int>(0.1 * group + s * bar);
      const int w = std::max(1, static_cast<int>(v / max_value * plot_width));
      cv::rectangle(out, cv::Point(left, y), cv::Point(left + w, y + static_cast<int>(bar) - 1),
                    series[s].colour, cv::FILLED);
      cv::putText(out, cv::format("%.1f", v),
                  cv::Point(left + w + 4, y + static_cast<int>(bar) - 2), kFont, 0.35, kInk, 1,
                  cv::LINE_AA);
    }
  }
  for (std::size_t s = 0; s < series.size(); ++s) {
    const int y = 40 + 22 * static_cast<int>(s);
    cv::rectangle(out, cv::Point(left, y - 10), cv::Point(left + 24, y), series[s].colour,
                  cv::FILLED);
    cv::putText(out, series[s].name, cv::Point(left + 32, y), kFont, 0.45, kInk, 1, cv::LINE_AA);
  }
  return out;
}

cv::Mat grid(const std::vector<std::vector<cv::Mat>>& rows) {
  std::vector<cv::Mat> stacked;
  int width = 0;
  for (const std::vector<cv::Mat>& row : rows) {
    if (row.empty()) continue;
    int height = 0;
    for (const cv::Mat& panel : row) height = std::max(height, panel.rows);
    std::vector<cv::Mat> padded;
    for (const cv::Mat& panel : row) {
      cv::Mat p;
      cv::copyMakeBorder(panel, p, 0, height - panel.rows, 0, 0, cv::BORDER_CONSTANT,
                         cv::Scalar(235, 235, 235));
      padded.push_back(p);
    }
    cv::Mat joined;
    cv::hconcat(padded, joined);
    width = std::max(width, joined.cols);
    stacked.push_back(joined);
  }
  for (cv::Mat& row : stacked) {
    cv::copyMakeBorder(row, row, 0, 0, 0, width - row.cols, cv::BORDER_CONSTANT,
                       cv::Scalar(235, 235, 235));
  }
  cv::Mat out;
  if (!stacked.empty()) cv::vconcat(stacked, out);
  return out;
}

}  // namespace ltlo::report
