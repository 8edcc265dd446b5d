// Small SVG charts for the model lab's HTML report (lab/lab_report.h).
//
// Line plots and grouped bar charts rendered as inline `<svg>` elements (no xmlns, no
// external reference: meant to be embedded in an HTML5 page): axes with "nice" ticks and
// tick labels, axis titles (put the units there, e.g. "time (s)", "tip (mm)"), a legend
// above the plot area, and `<title>` tooltips. Long series are downsampled to at most
// kMaxPointsPerLine points per line: for a series whose x never decreases (a time series)
// each bucket keeps its minimum and maximum, so peaks and spikes survive; for anything
// else (a hysteresis loop) every k-th point is kept. Non-finite points break a line.
// Data keep the caller's units; layout sizes are SVG pixels. All text is escaped.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace echoservo::report::svg {

inline constexpr std::size_t kMaxPointsPerLine = 2000;

// Escapes & < > " ' for HTML text and attribute values.
std::string EscapeHtml(std::string_view text);

// The CSS rules the charts' class names (tt, lg, tk, ax, vl, grid, frame) rely on; put it
// once into the page's <style>.
std::string_view ChartCss();

struct Line {
  std::string label;  // legend entry (omitted from the legend when empty)
  std::vector<double> x;
  std::vector<double> y;
  std::string color = "#1f77b4";
  double width = 1.5;
  bool dashed = false;
  double opacity = 1.0;
};

struct LinePlot {
  std::string title;
  std::string x_title;
  std::string y_title;
  std::vector<Line> lines;
  bool zero_line = false;  // a thin horizontal line at y = 0 (residual plots)
  int width = 600;
  int height = 320;
};

std::string RenderLinePlot(const LinePlot& plot);

struct BarSeries {
  std::string label;
  std::vector<double> values;  // one per category
  std::string color = "#4477aa";
};

struct ReferenceLine {
  std::string label;  // drawn at the right end of the line
  double value = 0.0;
  std::string color = "#666666";
};

struct BarChart {
  std::string title;
  std::string y_title;
  std::vector<std::string> categories;
  std::vector<BarSeries> series;
  std::vector<ReferenceLine> references;  // dashed horizontal lines (e.g. the noise level)
  int value_decimals = 3;                 // tooltips and value labels
  int width = 600;
  int height = 300;
};

std::string RenderBarChart(const BarChart& chart);

// Round tick values (steps 1, 2, 2.5 or 5 × 10^k) covering [lo, hi], about `count` of them.
std::vector<double> NiceTicks(double lo, double hi, int count);

// Indices of the points kept when `x`/`y` are drawn with at most `max_points` points
// (all of them when the series is short enough); ascending.
std::vector<std::size_t> DownsampleIndices(const std::vector<double>& x,
                                           const std::vector<double>& y,
                                           std::size_t max_points = kMaxPointsPerLine);

}  // namespace echoservo::report::svg
