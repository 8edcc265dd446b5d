#include "report/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace echoservo::report::svg {
namespace {

constexpr double kCharWidth = 6.2;  // average width of an 11 px sans-serif character
constexpr double kLeft = 66.0;
constexpr double kRight = 18.0;
constexpr double kTitleHeight = 24.0;
constexpr double kLegendRow = 17.0;

std::string Num(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string Px(double v) { return Num(v, 1); }

// Decimals needed to print multiples of `step` exactly.
int StepDecimals(double step) {
  for (int d = 0; d < 10; ++d) {
    const double s = step * std::pow(10.0, d);
    if (std::abs(s - std::round(s)) < 1e-6 * std::max(1.0, std::abs(s))) return d;
  }
  return 10;
}

struct Axis {
  double lo = 0.0;
  double hi = 1.0;
  std::vector<double> ticks;
  int decimals = 0;
  double Map(double v, double p0, double p1) const { return p0 + (v - lo) / (hi - lo) * (p1 - p0); }
};

Axis MakeAxis(double lo, double hi, int count) {
  Axis a;
  a.ticks = NiceTicks(lo, hi, count);
  a.lo = a.ticks.front();
  a.hi = a.ticks.back();
  a.decimals = a.ticks.size() > 1 ? StepDecimals(a.ticks[1] - a.ticks[0]) : 0;
  return a;
}

std::string TickLabel(double v, const Axis& a) {
  const double step = a.ticks.size() > 1 ? a.ticks[1] - a.ticks[0] : 1.0;
  if (std::abs(v) < 1e-9 * step) v = 0.0;  // no "-0.00"
  return Num(v, a.decimals);
}

double TextWidth(std::string_view text) { return kCharWidth * static_cast<double>(text.size()); }

std::string Truncate(const std::string& text, std::size_t max_chars) {
  if (text.size() <= max_chars) return text;
  std::string out = text.substr(0, max_chars - 1);
  while (!out.empty() && (static_cast<unsigned char>(out.back()) & 0xC0) == 0x80)
    out.pop_back();  // UTF-8
  if (!out.empty() && (static_cast<unsigned char>(out.back()) & 0x80) != 0) out.pop_back();
  return out + "\u2026";
}

struct LegendItem {
  std::string label;
  std::string color;
  bool dashed = false;
  bool box = false;  // a filled square (bars) instead of a line
};

// Rows needed for the legend items in `width` pixels.
std::vector<std::vector<const LegendItem*>> LegendRows(const std::vector<LegendItem>& items,
                                                       double width) {
  std::vector<std::vector<const LegendItem*>> rows;
  double x = 0.0;
  for (const LegendItem& it : items) {
    const double w = 26.0 + TextWidth(it.label) + 16.0;
    if (rows.empty() || (x + w > width && !rows.back().empty())) {
      rows.emplace_back();
      x = 0.0;
    }
    rows.back().push_back(&it);
    x += w;
  }
  return rows;
}

void DrawLegend(std::string& s, const std::vector<std::vector<const LegendItem*>>& rows, double x0,
                double y0) {
  double y = y0;
  for (const auto& row : rows) {
    double x = x0;
    for (const LegendItem* it : row) {
      if (it->box) {
        s += "<rect x=\"" + Px(x) + "\" y=\"" + Px(y - 8) +
             "\" width=\"18\" height=\"10\" fill=\"" + it->color + "\"/>";
      } else {
        s += "<line x1=\"" + Px(x) + "\" y1=\"" + Px(y - 3) + "\" x2=\"" + Px(x + 18) + "\" y2=\"" +
             Px(y - 3) + "\" stroke=\"" + it->color + "\" stroke-width=\"2.5\"" +
             (it->dashed ? " stroke-dasharray=\"5,3\"" : "") + "/>";
      }
      s += "<text x=\"" + Px(x + 24) + "\" y=\"" + Px(y) + "\" class=\"lg\">" +
           EscapeHtml(it->label) + "</text>";
      x += 26.0 + TextWidth(it->label) + 16.0;
    }
    y += kLegendRow;
  }
}

std::string SvgOpen(int width, int height, const std::string& title) {
  return "<svg class=\"chart\" viewBox=\"0 0 " + std::to_string(width) + " " +
         std::to_string(height) + "\" width=\"" + std::to_string(width) + "\" height=\"" +
         std::to_string(height) + "\" role=\"img\" aria-label=\"" + EscapeHtml(title) + "\">" +
         "<rect x=\"0\" y=\"0\" width=\"" + std::to_string(width) + "\" height=\"" +
         std::to_string(height) + "\" fill=\"#ffffff\"/>";
}

void DrawTitle(std::string& s, const std::string& title, int width) {
  if (title.empty()) return;
  s += "<text x=\"" + Px(width / 2.0) + "\" y=\"16\" text-anchor=\"middle\" class=\"tt\">" +
       EscapeHtml(title) + "</text>";
}

// Horizontal grid lines, y tick labels and the rotated y title.
void DrawYAxis(std::string& s, const Axis& ya, double left, double right, double top, double bottom,
               const std::string& y_title) {
  for (double t : ya.ticks) {
    const double y = ya.Map(t, bottom, top);
    s += "<line x1=\"" + Px(left) + "\" y1=\"" + Px(y) + "\" x2=\"" + Px(right) + "\" y2=\"" +
         Px(y) + "\" class=\"grid\"/>";
    s += "<text x=\"" + Px(left - 5) + "\" y=\"" + Px(y + 4) +
         "\" text-anchor=\"end\" class=\"tk\">" + TickLabel(t, ya) + "</text>";
  }
  const double mid = (top + bottom) / 2.0;
  s += "<text x=\"14\" y=\"" + Px(mid) + "\" text-anchor=\"middle\" transform=\"rotate(-90 14 " +
       Px(mid) + ")\" class=\"ax\">" + EscapeHtml(y_title) + "</text>";
}

}  // namespace

std::string_view ChartCss() {
  return "svg.chart{max-width:100%;height:auto;font-family:inherit}"
         "svg.chart .tt{font-size:13px;font-weight:600;fill:#222}"
         "svg.chart .lg{font-size:11px;fill:#333}"
         "svg.chart .tk{font-size:10.5px;fill:#444}"
         "svg.chart .ax{font-size:11.5px;fill:#222}"
         "svg.chart .vl{font-size:10px;fill:#333}"
         "svg.chart .grid{stroke:#e6e6e6;stroke-width:1}"
         "svg.chart .frame{fill:none;stroke:#999;stroke-width:1}";
}

std::string EscapeHtml(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::vector<double> NiceTicks(double lo, double hi, int count) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    lo = 0.0;
    hi = 1.0;
  }
  if (lo > hi) std::swap(lo, hi);
  if (hi - lo <= 1e-12 * std::max(std::abs(lo), std::abs(hi))) {  // a single value
    const double pad = lo == 0.0 ? 1.0 : 0.1 * std::abs(lo);
    lo -= pad;
    hi += pad;
  }
  count = std::max(count, 2);
  const double raw = (hi - lo) / count;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double frac = raw / mag;
  const double nice = frac <= 1.0   ? 1.0
                      : frac <= 2.0 ? 2.0
                      : frac <= 2.5 ? 2.5
                      : frac <= 5.0 ? 5.0
                                    : 10.0;
  const double step = nice * mag;
  const double first = std::floor(lo / step + 1e-9);
  const double last = std::ceil(hi / step - 1e-9);
  std::vector<double> ticks;
  for (double k = first; k <= last + 0.5; k += 1.0) ticks.push_back(k * step);
  if (ticks.size() < 2) ticks.push_back(ticks.back() + step);
  return ticks;
}

std::vector<std::size_t> DownsampleIndices(const std::vector<double>& x,
                                           const std::vector<double>& y, std::size_t max_points) {
  const std::size_t n = std::min(x.size(), y.size());
  std::vector<std::size_t> out;
  max_points = std::max<std::size_t>(max_points, 6);
  if (n <= max_points) {
    for (std::size_t i = 0; i < n; ++i) out.push_back(i);
    return out;
  }
  bool monotonic = true;
  bool gaps = false;
  double prev = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
      gaps = true;
      continue;
    }
    if (x[i] < prev) monotonic = false;
    prev = x[i];
  }
  if (!monotonic) {  // every k-th point, first and last included
    for (std::size_t j = 0; j < max_points; ++j) {
      const std::size_t i = static_cast<std::size_t>(
          std::llround(static_cast<double>(j) * static_cast<double>(n - 1) /
                       static_cast<double>(max_points - 1)));
      if (out.empty() || i != out.back()) out.push_back(i);
    }
    return out;
  }
  // Minimum and maximum of every bucket (and its first gap, so the line still breaks).
  const std::size_t buckets = max_points / (gaps ? 3 : 2);
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t i0 = b * n / buckets;
    const std::size_t i1 = (b + 1) * n / buckets;
    std::size_t lo = n, hi = n, gap = n;
    for (std::size_t i = i0; i < i1; ++i) {
      if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
        if (gap == n) gap = i;
        continue;
      }
      if (lo == n || y[i] < y[lo]) lo = i;
      if (hi == n || y[i] > y[hi]) hi = i;
    }
    std::vector<std::size_t> keep;
    for (std::size_t i : {lo, hi, gap}) {
      if (i != n) keep.push_back(i);
    }
    std::sort(keep.begin(), keep.end());
    for (std::size_t i : keep) {
      if (out.empty() || i != out.back()) out.push_back(i);
    }
  }
  return out;
}

std::string RenderLinePlot(const LinePlot& p) {
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin, ymin = xmin, ymax = -xmin;
  for (const Line& l : p.lines) {
    for (std::size_t i = 0; i < std::min(l.x.size(), l.y.size()); ++i) {
      if (!std::isfinite(l.x[i]) || !std::isfinite(l.y[i])) continue;
      xmin = std::min(xmin, l.x[i]);
      xmax = std::max(xmax, l.x[i]);
      ymin = std::min(ymin, l.y[i]);
      ymax = std::max(ymax, l.y[i]);
    }
  }
  if (!std::isfinite(xmin)) xmin = 0.0, xmax = 1.0, ymin = 0.0, ymax = 1.0;
  if (p.zero_line) ymin = std::min(ymin, 0.0), ymax = std::max(ymax, 0.0);

  std::vector<LegendItem> items;
  for (const Line& l : p.lines) {
    if (!l.label.empty()) items.push_back({l.label, l.color, l.dashed, false});
  }
  const double right = p.width - kRight;
  const auto rows = LegendRows(items, right - kLeft);
  const double top = kTitleHeight + kLegendRow * static_cast<double>(rows.size()) + 8.0;
  const double bottom = p.height - 40.0;
  const Axis xa = MakeAxis(xmin, xmax, std::max(3, static_cast<int>((right - kLeft) / 85.0)));
  const Axis ya = MakeAxis(ymin, ymax, std::max(3, static_cast<int>((bottom - top) / 42.0)));

  std::string s = SvgOpen(p.width, p.height, p.title);
  DrawTitle(s, p.title, p.width);
  DrawLegend(s, rows, kLeft, kTitleHeight + 12.0);
  DrawYAxis(s, ya, kLeft, right, top, bottom, p.y_title);
  for (double t : xa.ticks) {
    const double x = xa.Map(t, kLeft, right);
    s += "<line x1=\"" + Px(x) + "\" y1=\"" + Px(top) + "\" x2=\"" + Px(x) + "\" y2=\"" +
         Px(bottom) + "\" class=\"grid\"/>";
    s += "<text x=\"" + Px(x) + "\" y=\"" + Px(bottom + 15) +
         "\" text-anchor=\"middle\" class=\"tk\">" + TickLabel(t, xa) + "</text>";
  }
  s += "<text x=\"" + Px((kLeft + right) / 2.0) + "\" y=\"" + Px(p.height - 8.0) +
       "\" text-anchor=\"middle\" class=\"ax\">" + EscapeHtml(p.x_title) + "</text>";
  if (p.zero_line) {
    const double y = ya.Map(0.0, bottom, top);
    s += "<line x1=\"" + Px(kLeft) + "\" y1=\"" + Px(y) + "\" x2=\"" + Px(right) + "\" y2=\"" +
         Px(y) + "\" stroke=\"#555\" stroke-width=\"1\"/>";
  }
  for (const Line& l : p.lines) {
    const std::vector<std::size_t> idx = DownsampleIndices(l.x, l.y);
    std::string attrs = "fill=\"none\" stroke=\"" + l.color + "\" stroke-width=\"" +
                        Num(l.width, 2) + "\" stroke-linejoin=\"round\" stroke-linecap=\"round\"";
    if (l.dashed) attrs += " stroke-dasharray=\"6,4\"";
    if (l.opacity < 1.0) attrs += " stroke-opacity=\"" + Num(l.opacity, 2) + "\"";
    std::string points;
    std::size_t count = 0;
    auto flush = [&] {
      if (count >= 2) s += "<polyline " + attrs + " points=\"" + points + "\"/>";
      points.clear();
      count = 0;
    };
    for (std::size_t i : idx) {
      if (!std::isfinite(l.x[i]) || !std::isfinite(l.y[i])) {
        flush();
        continue;
      }
      if (count > 0) points += ' ';
      points += Px(xa.Map(l.x[i], kLeft, right)) + "," + Px(ya.Map(l.y[i], bottom, top));
      ++count;
    }
    flush();
  }
  s += "<rect x=\"" + Px(kLeft) + "\" y=\"" + Px(top) + "\" width=\"" + Px(right - kLeft) +
       "\" height=\"" + Px(bottom - top) + "\" class=\"frame\"/>";
  s += "</svg>";
  return s;
}

std::string RenderBarChart(const BarChart& c) {
  const std::size_t n = c.categories.size();
  double vmin = 0.0, vmax = 0.0;
  for (const BarSeries& b : c.series) {
    for (double v : b.values) {
      if (std::isfinite(v)) vmin = std::min(vmin, v), vmax = std::max(vmax, v);
    }
  }
  for (const ReferenceLine& r : c.references) {
    if (std::isfinite(r.value)) vmin = std::min(vmin, r.value), vmax = std::max(vmax, r.value);
  }
  if (vmax <= vmin) vmax = vmin + 1.0;

  std::vector<LegendItem> items;
  if (c.series.size() > 1) {
    for (const BarSeries& b : c.series) items.push_back({b.label, b.color, false, true});
  }
  for (const ReferenceLine& r : c.references) items.push_back({r.label, r.color, true, false});
  const double right = c.width - kRight;
  const auto rows = LegendRows(items, right - kLeft);
  const double top = kTitleHeight + kLegendRow * static_cast<double>(rows.size()) + 8.0;
  const double group = n > 0 ? (right - kLeft) / static_cast<double>(n) : right - kLeft;
  constexpr std::size_t kMaxLabel = 30;
  double longest = 0.0;
  for (const std::string& cat : c.categories)
    longest = std::max(longest, TextWidth(Truncate(cat, kMaxLabel)));
  const bool rotate = longest > group - 6.0;
  const double label_room = rotate ? 0.55 * longest + 16.0 : 18.0;
  const double height = c.height + (rotate ? std::max(0.0, label_room - 18.0) : 0.0);
  const double bottom = height - label_room - 6.0;
  // Values printed above the bars when they fit (tooltips carry them otherwise); leave
  // headroom for them under the top of the frame.
  const std::size_t ns = std::max<std::size_t>(c.series.size(), 1);
  const double bar = std::min(group * 0.72 / static_cast<double>(ns), 56.0);
  std::size_t widest = 0;
  for (const BarSeries& b : c.series) {
    for (double v : b.values) widest = std::max(widest, Num(v, c.value_decimals).size());
  }
  const bool value_labels = bar - 2.0 >= 5.6 * static_cast<double>(widest) + 2.0;
  if (value_labels) vmax += 0.08 * (vmax - vmin);
  const Axis ya = MakeAxis(vmin, vmax, std::max(3, static_cast<int>((bottom - top) / 42.0)));

  std::string s = SvgOpen(c.width, static_cast<int>(height), c.title);
  DrawTitle(s, c.title, c.width);
  DrawLegend(s, rows, kLeft, kTitleHeight + 12.0);
  DrawYAxis(s, ya, kLeft, right, top, bottom, c.y_title);

  const double zero = ya.Map(0.0, bottom, top);
  for (std::size_t k = 0; k < n; ++k) {
    const double center = kLeft + group * (static_cast<double>(k) + 0.5);
    const double x0 = center - bar * static_cast<double>(ns) / 2.0;
    for (std::size_t j = 0; j < c.series.size(); ++j) {
      const BarSeries& b = c.series[j];
      if (k >= b.values.size() || !std::isfinite(b.values[k])) continue;
      const double v = b.values[k];
      const double y = ya.Map(v, bottom, top);
      const double x = x0 + bar * static_cast<double>(j);
      s += "<rect x=\"" + Px(x + 1) + "\" y=\"" + Px(std::min(y, zero)) + "\" width=\"" +
           Px(bar - 2) + "\" height=\"" + Px(std::abs(zero - y)) + "\" fill=\"" + b.color +
           "\"><title>" + EscapeHtml(c.categories[k]) +
           (b.label.empty() ? "" : " \u2014 " + EscapeHtml(b.label)) + ": " +
           Num(v, c.value_decimals) + "</title></rect>";
      if (value_labels) {
        s += "<text x=\"" + Px(x + bar / 2.0) + "\" y=\"" + Px(std::min(y, zero) - 3.0) +
             "\" text-anchor=\"middle\" class=\"vl\">" + Num(v, c.value_decimals) + "</text>";
      }
    }
    const std::string label = EscapeHtml(Truncate(c.categories[k], kMaxLabel));
    if (rotate) {
      const double ly = bottom + 12.0;
      s += "<text x=\"" + Px(center) + "\" y=\"" + Px(ly) +
           "\" text-anchor=\"end\" transform=\"rotate(-35 " + Px(center) + " " + Px(ly) +
           ")\" class=\"tk\"><title>" + EscapeHtml(c.categories[k]) + "</title>" + label +
           "</text>";
    } else {
      s += "<text x=\"" + Px(center) + "\" y=\"" + Px(bottom + 15.0) +
           "\" text-anchor=\"middle\" class=\"tk\">" + label + "</text>";
    }
  }
  s += "<line x1=\"" + Px(kLeft) + "\" y1=\"" + Px(zero) + "\" x2=\"" + Px(right) + "\" y2=\"" +
       Px(zero) + "\" stroke=\"#555\" stroke-width=\"1\"/>";
  for (const ReferenceLine& r : c.references) {
    if (!std::isfinite(r.value)) continue;
    const double y = ya.Map(r.value, bottom, top);
    s += "<line x1=\"" + Px(kLeft) + "\" y1=\"" + Px(y) + "\" x2=\"" + Px(right) + "\" y2=\"" +
         Px(y) + "\" stroke=\"" + r.color +
         "\" stroke-width=\"1.5\" stroke-dasharray=\"6,4\"><title>" + EscapeHtml(r.label) + ": " +
         Num(r.value, c.value_decimals) + "</title></line>";
  }
  s += "<rect x=\"" + Px(kLeft) + "\" y=\"" + Px(top) + "\" width=\"" + Px(right - kLeft) +
       "\" height=\"" + Px(bottom - top) + "\" class=\"frame\"/>";
  s += "</svg>";
  return s;
}

}  // namespace echoservo::report::svg
