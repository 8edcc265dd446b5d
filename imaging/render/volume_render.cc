// The 2D slice/MIP panel (OpenCV) and the synthetic phantom. The VTK half lives in
// volume_render_3d.cc.
#include "imaging/render/volume_render.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "imaging/render/png_file.h"
#include "imaging/render/render_overlays_check.h"

namespace echoservo::imaging {
namespace {

constexpr int kPanelTargetPx = 320;  // the longest volume edge is drawn about this long
constexpr int kLeftMargin = 64;
constexpr int kGap = 64;          // between columns (room for the next vertical ticks)
constexpr int kHeader = 44;       // title lines
constexpr int kPanelTitle = 40;   // above each panel: title, vertical axis name
constexpr int kPanelBottom = 40;  // below each panel: ticks and axis name
constexpr int kLegend = 96;       // legend and scale bar
constexpr int kMinWidth = 760;

const cv::Scalar kBackground(32, 32, 32);
const cv::Scalar kText(235, 235, 235);
const cv::Scalar kDimText(170, 170, 170);
const cv::Scalar kAxisColour(0, 220, 255);    // yellow: detected axis
const cv::Scalar kTipColour(60, 60, 255);     // red: detected tip
const cv::Scalar kTargetColour(60, 220, 60);  // green: detected target
const cv::Scalar kTruthColour(255, 230, 0);   // cyan: ground truth
const cv::Scalar kSliceTick(255, 80, 255);    // magenta: where the other slices are
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.42;

const char* const kAxisNames[3] = {"x", "y", "z"};
const char* const kIndexNames[3] = {"i", "j", "k"};

std::string Fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string FmtPoint(const Eigen::Vector3d& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.1f, %.1f, %.1f) mm", p.x(), p.y(), p.z());
  return buf;
}

void PutText(cv::Mat& img, const std::string& text, cv::Point org, const cv::Scalar& colour,
             double scale = kFontScale) {
  cv::putText(img, text, org, kFont, scale, colour, 1, cv::LINE_AA);
}

int TextWidth(const std::string& text, double scale = kFontScale) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, 1, &baseline).width;
}

// 1, 2 or 5 × 10^n, the smallest with step·ppm ≥ min_px.
double NiceStep(double pixels_per_mm, double min_px) {
  const double raw = min_px / pixels_per_mm;
  const double p10 = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p10 >= raw) return m * p10;
  }
  return 10.0 * p10;
}

bool IsIdentityDirection(const Volume& v) {
  return (v.direction() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9;
}

// Pixel scale of a panel along one index axis (px per voxel), exact for its size.
double PxPerVoxel(const SlicePanelLayout::Panel& p, const Volume& v, bool horizontal) {
  return horizontal ? static_cast<double>(p.width) / v.dims()[p.u_axis]
                    : static_cast<double>(p.height) / v.dims()[p.v_axis];
}

Eigen::Vector2d IndexToPanelPx(const Volume& v, const SlicePanelLayout::Panel& p,
                               const Eigen::Vector3d& index) {
  return {p.x0 + (index[p.u_axis] + 0.5) * PxPerVoxel(p, v, true) - 0.5,
          p.y0 + (index[p.v_axis] + 0.5) * PxPerVoxel(p, v, false) - 0.5};
}

// The 2D image (dims[v] rows × dims[u] columns) of a slice or a MIP.
cv::Mat PanelImage(const Volume& volume, const SlicePanelLayout::Panel& p, bool mip, int slice) {
  const Eigen::Vector3i& d = volume.dims();
  cv::Mat img(d[p.v_axis], d[p.u_axis], CV_8U, cv::Scalar(0));
  int idx[3];
  for (int b = 0; b < d[p.v_axis]; ++b) {
    auto* row = img.ptr<std::uint8_t>(b);
    for (int a = 0; a < d[p.u_axis]; ++a) {
      idx[p.u_axis] = a;
      idx[p.v_axis] = b;
      if (!mip) {
        idx[p.normal_axis] = slice;
        row[a] = volume.at(idx[0], idx[1], idx[2]);
        continue;
      }
      std::uint8_t m = 0;
      for (int c = 0; c < d[p.normal_axis]; ++c) {
        idx[p.normal_axis] = c;
        m = std::max(m, volume.at(idx[0], idx[1], idx[2]));
      }
      row[a] = m;
    }
  }
  return img;
}

// Anti-aliased line with sub-pixel end points.
void Line(cv::Mat& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
          const cv::Scalar& colour, int thickness) {
  constexpr int kShift = 4;
  constexpr double kScale = 1 << kShift;
  cv::line(img, cv::Point(cvRound(a.x() * kScale), cvRound(a.y() * kScale)),
           cv::Point(cvRound(b.x() * kScale), cvRound(b.y() * kScale)), colour, thickness,
           cv::LINE_AA, kShift);
}

void DashedLine(cv::Mat& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                const cv::Scalar& colour, int thickness) {
  const double len = (b - a).norm();
  if (len < 1e-9) return;
  const Eigen::Vector2d dir = (b - a) / len;
  constexpr double kDash = 7.0, kSpace = 5.0;
  for (double s = 0.0; s < len; s += kDash + kSpace) {
    Line(img, a + dir * s, a + dir * std::min(len, s + kDash), colour, thickness);
  }
}

// Clips the infinite line p + t·d to the index box [-0.5, dims − 0.5]; nullopt if it misses.
std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> ClipLineToVolume(
    const Volume& v, const Eigen::Vector3d& point_mm, const Eigen::Vector3d& dir_mm) {
  const Eigen::Vector3d p = v.PhysicalToIndex(point_mm);
  const Eigen::Vector3d d = v.PhysicalToIndex(point_mm + dir_mm) - p;
  double t0 = -std::numeric_limits<double>::infinity();
  double t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double lo = -0.5, hi = v.dims()[a] - 0.5;
    if (std::abs(d[a]) < 1e-12) {
      if (p[a] < lo || p[a] > hi) return std::nullopt;
      continue;
    }
    double ta = (lo - p[a]) / d[a], tb = (hi - p[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 <= t1)) return std::nullopt;
  return std::make_pair(Eigen::Vector3d(p + t0 * d), Eigen::Vector3d(p + t1 * d));
}

struct OverlayStyle {
  cv::Scalar axis, tip, target;
  bool dashed = false;
  int tip_marker = cv::MARKER_TILTED_CROSS;
  int target_marker = cv::MARKER_DIAMOND;
  int thickness = 2;
};

void DrawOverlaySet(cv::Mat& canvas, const Volume& volume, const SlicePanelLayout& layout,
                    const std::optional<Eigen::Vector3d>& axis_point,
                    const std::optional<Eigen::Vector3d>& axis_dir,
                    const std::optional<Eigen::Vector3d>& tip,
                    const std::optional<Eigen::Vector3d>& target, const OverlayStyle& style) {
  std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> seg;
  if (axis_point && axis_dir) seg = ClipLineToVolume(volume, *axis_point, *axis_dir);
  for (const auto& p : layout.panels) {
    cv::Mat roi = canvas(cv::Rect(p.x0, p.y0, p.width, p.height));  // clips the drawing
    const Eigen::Vector2d off(p.x0, p.y0);
    if (seg) {
      const Eigen::Vector2d a = IndexToPanelPx(volume, p, seg->first) - off;
      const Eigen::Vector2d b = IndexToPanelPx(volume, p, seg->second) - off;
      if (style.dashed) {
        DashedLine(roi, a, b, style.axis, 1);
      } else {
        Line(roi, a, b, style.axis, 1);
      }
    }
    if (tip) {
      const Eigen::Vector2d q = IndexToPanelPx(volume, p, volume.PhysicalToIndex(*tip)) - off;
      cv::drawMarker(roi, cv::Point(cvRound(q.x()), cvRound(q.y())), style.tip, style.tip_marker,
                     14, style.thickness, cv::LINE_AA);
    }
    if (target) {
      const Eigen::Vector2d q = IndexToPanelPx(volume, p, volume.PhysicalToIndex(*target)) - off;
      cv::drawMarker(roi, cv::Point(cvRound(q.x()), cvRound(q.y())), style.target,
                     style.target_marker, 14, style.thickness, cv::LINE_AA);
    }
  }
}

// Tick labels along one edge of a panel: `horizontal` → below it, else left of it.
void DrawTicks(cv::Mat& canvas, const Volume& volume, const SlicePanelLayout& layout,
               const SlicePanelLayout::Panel& p, bool horizontal) {
  const int axis = horizontal ? p.u_axis : p.v_axis;
  const bool frame_coords = IsIdentityDirection(volume);
  const double origin = frame_coords ? volume.origin_mm()[axis] : 0.0;
  const double sp = volume.spacing_mm()[axis];
  const double lo = origin - 0.5 * sp, hi = origin + (volume.dims()[axis] - 0.5) * sp;
  const double step = NiceStep(layout.pixels_per_mm, horizontal ? 60.0 : 40.0);
  const double pxv = PxPerVoxel(p, volume, horizontal);
  const int decimals = step < 1.0 ? 1 : 0;
  for (double c = std::ceil(lo / step) * step; c <= hi + 1e-9; c += step) {
    const double idx = (c - origin) / sp;
    const double px = (idx + 0.5) * pxv - 0.5;
    const std::string label = Fmt(decimals ? "%.1f" : "%.0f", std::abs(c) < 1e-9 ? 0.0 : c);
    if (horizontal) {
      const int x = p.x0 + cvRound(px), y = p.y0 + p.height;
      cv::line(canvas, {x, y}, {x, y + 4}, kDimText, 1);
      PutText(canvas, label, {x - TextWidth(label) / 2, y + 17}, kDimText);
    } else {
      const int x = p.x0, y = p.y0 + cvRound(px);
      cv::line(canvas, {x - 4, y}, {x, y}, kDimText, 1);
      PutText(canvas, label, {x - 7 - TextWidth(label), y + 5}, kDimText);
    }
  }
  const std::string name = frame_coords
                               ? std::string(kAxisNames[axis]) + " (mm)"
                               : std::string(kIndexNames[axis]) + " axis (mm from voxel 0)";
  if (horizontal) {
    PutText(canvas, name + "  ->", {p.x0 + p.width / 2 - TextWidth(name) / 2, p.y0 + p.height + 34},
            kText);
  } else {
    // Vertical axis name at the top-left corner, pointing down.
    PutText(canvas, name + " v", {p.x0 - kLeftMargin + 4, p.y0 - 6}, kText);
  }
}

}  // namespace

SlicePanelLayout ComputeSlicePanelLayout(const Volume& volume, const RenderOverlays& overlays) {
  CheckOverlays(overlays);
  SlicePanelLayout layout;
  const Eigen::Vector3i& d = volume.dims();
  const Eigen::Vector3d ext = d.cast<double>().cwiseProduct(volume.spacing_mm());
  layout.pixels_per_mm = std::clamp(kPanelTargetPx / ext.maxCoeff(), 0.05, 60.0);
  auto px = [&](int axis) { return std::max(1, cvRound(ext[axis] * layout.pixels_per_mm)); };

  const int planes[3][3] = {{0, 1, 2}, {0, 2, 1}, {1, 2, 0}};  // u, v, normal
  int row_height = 0;
  for (const auto& pl : planes) row_height = std::max(row_height, px(pl[1]));
  int x = kLeftMargin;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 2; ++r) {
      SlicePanelLayout::Panel& p = layout.panels[static_cast<std::size_t>(r * 3 + c)];
      p.u_axis = planes[c][0];
      p.v_axis = planes[c][1];
      p.normal_axis = planes[c][2];
      p.width = px(p.u_axis);
      p.height = px(p.v_axis);
      p.x0 = x;
      p.y0 = kHeader + r * (kPanelTitle + row_height + kPanelBottom) + kPanelTitle;
    }
    x += px(planes[c][0]) + kGap;
  }
  layout.image_width = std::max(kMinWidth, x - kGap + 24);
  layout.image_height = kHeader + 2 * (kPanelTitle + row_height + kPanelBottom) + kLegend;

  Eigen::Vector3d centre;
  if (overlays.slice_point_mm) {
    centre = volume.PhysicalToIndex(*overlays.slice_point_mm);
  } else if (overlays.tip_mm) {
    centre = volume.PhysicalToIndex(*overlays.tip_mm);
  } else if (overlays.truth && overlays.truth->catheter_visible) {
    centre = volume.PhysicalToIndex(overlays.truth->tip_mm);
  } else {
    centre = (d.cast<double>() - Eigen::Vector3d::Ones()) / 2.0;
  }
  for (int a = 0; a < 3; ++a) {
    layout.slice_index[a] = std::clamp(std::round(centre[a]), 0.0, d[a] - 1.0);
  }
  return layout;
}

Eigen::Vector2d ProjectToPanel(const Volume& volume, const SlicePanelLayout& layout, int panel,
                               const Eigen::Vector3d& point_mm) {
  if (panel < 0 || panel >= 6) throw std::invalid_argument("ProjectToPanel: panel out of 0..5");
  return IndexToPanelPx(volume, layout.panels[static_cast<std::size_t>(panel)],
                        volume.PhysicalToIndex(point_mm));
}

void RenderSlicesPng(const Volume& volume, const RenderOverlays& overlays,
                     const std::filesystem::path& png) {
  const SlicePanelLayout layout = ComputeSlicePanelLayout(volume, overlays);
  cv::Mat canvas(layout.image_height, layout.image_width, CV_8UC3, kBackground);

  // Header.
  const Eigen::Vector3i& d = volume.dims();
  const Eigen::Vector3d& s = volume.spacing_mm();
  char geo[200];
  std::snprintf(geo, sizeof geo,
                "%d x %d x %d voxels, spacing %.2f x %.2f x %.2f mm, frame %lld, t = %.3f s%s",
                d.x(), d.y(), d.z(), s.x(), s.y(), s.z(),
                static_cast<long long>(volume.frame_index()), volume.timestamp_s(),
                IsIdentityDirection(volume) ? "" : ", oblique: axes are index axes");
  PutText(canvas, overlays.title.empty() ? "echoservo render" : overlays.title, {kLeftMargin, 18},
          kText, 0.5);
  PutText(canvas, geo, {kLeftMargin, 36}, kDimText);

  // Volume images.
  for (std::size_t n = 0; n < layout.panels.size(); ++n) {
    const auto& p = layout.panels[n];
    const bool mip = n >= 3;
    const int slice = static_cast<int>(layout.slice_index[p.normal_axis]);
    cv::Mat img = PanelImage(volume, p, mip, slice);
    const double scale =
        std::min(static_cast<double>(p.width) / img.cols, static_cast<double>(p.height) / img.rows);
    const int interp = scale >= 2.0   ? cv::INTER_NEAREST
                       : scale >= 1.0 ? cv::INTER_LINEAR
                                      : cv::INTER_AREA;
    cv::Mat resized, bgr;
    cv::resize(img, resized, cv::Size(p.width, p.height), 0, 0, interp);
    cv::cvtColor(resized, bgr, cv::COLOR_GRAY2BGR);
    bgr.copyTo(canvas(cv::Rect(p.x0, p.y0, p.width, p.height)));
    cv::rectangle(canvas, cv::Rect(p.x0 - 1, p.y0 - 1, p.width + 2, p.height + 2), kDimText, 1);

    std::string title;
    const int n_ax = p.normal_axis;
    if (mip) {
      title = std::string("MIP along ") + kAxisNames[n_ax];
    } else {
      const double pos = IsIdentityDirection(volume) ? volume.origin_mm()[n_ax] + slice * s[n_ax]
                                                     : slice * s[n_ax];
      title = std::string("slice ") + kAxisNames[n_ax] + " = " + Fmt("%.1f", pos) + " mm (" +
              kIndexNames[n_ax] + " " + std::to_string(slice) + ")";
      // Where the other two slices cut this one.
      const Eigen::Vector2d c =
          IndexToPanelPx(volume, p, layout.slice_index) - Eigen::Vector2d(p.x0, p.y0);
      const int cx = p.x0 + cvRound(c.x()), cy = p.y0 + cvRound(c.y());
      cv::line(canvas, {cx, p.y0 - 1}, {cx, p.y0 + 5}, kSliceTick, 2);
      cv::line(canvas, {cx, p.y0 + p.height - 6}, {cx, p.y0 + p.height}, kSliceTick, 2);
      cv::line(canvas, {p.x0 - 1, cy}, {p.x0 + 5, cy}, kSliceTick, 2);
      cv::line(canvas, {p.x0 + p.width - 6, cy}, {p.x0 + p.width, cy}, kSliceTick, 2);
    }
    PutText(canvas, title, {p.x0, p.y0 - 24}, kText);
    DrawTicks(canvas, volume, layout, p, true);
    DrawTicks(canvas, volume, layout, p, false);
  }

  // Overlays: truth first (thin, dashed, cyan) so the detections stay on top.
  if (overlays.truth) {
    const FrameGroundTruth& t = *overlays.truth;
    OverlayStyle truth{
        kTruthColour, kTruthColour, kTruthColour, true, cv::MARKER_CROSS, cv::MARKER_SQUARE, 1};
    std::optional<Eigen::Vector3d> none;
    DrawOverlaySet(canvas, volume, layout,
                   t.catheter_visible ? std::optional(t.axis_point_mm) : none,
                   t.catheter_visible ? std::optional(t.axis_direction) : none,
                   t.catheter_visible ? std::optional(t.tip_mm) : none,
                   t.target_visible ? std::optional(t.target_mm) : none, truth);
  }
  DrawOverlaySet(canvas, volume, layout, overlays.axis_point_mm, overlays.axis_direction,
                 overlays.tip_mm, overlays.target_mm,
                 OverlayStyle{kAxisColour, kTipColour, kTargetColour});

  // Legend and scale bar.
  int y = layout.image_height - kLegend + 22;
  int x = kLeftMargin;
  auto entry = [&](const std::string& text, const cv::Scalar& colour, int marker, bool line,
                   bool dashed) {
    if (line) {
      if (dashed) {
        DashedLine(canvas, {x - 2.0, y - 4.0}, {x + 22.0, y - 4.0}, colour, 1);
      } else {
        Line(canvas, {x - 2.0, y - 4.0}, {x + 22.0, y - 4.0}, colour, 2);
      }
    } else {
      cv::drawMarker(canvas, {x + 10, y - 4}, colour, marker, 12, 2, cv::LINE_AA);
    }
    PutText(canvas, text, {x + 30, y}, kText);
    x += 30 + TextWidth(text) + 24;
  };
  bool any = false;
  if (overlays.axis_point_mm && overlays.axis_direction) {
    entry("axis", kAxisColour, 0, true, false);
    any = true;
  }
  if (overlays.tip_mm) {
    entry("tip " + FmtPoint(*overlays.tip_mm), kTipColour, cv::MARKER_TILTED_CROSS, false, false);
    any = true;
  }
  if (overlays.target_mm) {
    entry("target " + FmtPoint(*overlays.target_mm), kTargetColour, cv::MARKER_DIAMOND, false,
          false);
    any = true;
  }
  if (any) {
    y += 24;
    x = kLeftMargin;
  }
  if (overlays.truth) {
    const FrameGroundTruth& t = *overlays.truth;
    if (t.catheter_visible) {
      entry("true axis", kTruthColour, 0, true, true);
      entry("true tip " + FmtPoint(t.tip_mm), kTruthColour, cv::MARKER_CROSS, false, false);
    }
    if (t.target_visible) {
      entry("true target " + FmtPoint(t.target_mm), kTruthColour, cv::MARKER_SQUARE, false, false);
    }
    if (!t.catheter_visible && !t.target_visible) {
      PutText(canvas, "ground truth: catheter and target not visible", {x, y}, kTruthColour);
    }
    y += 24;
    x = kLeftMargin;
  }
  PutText(canvas, "magenta ticks: slice positions", {x, y}, kDimText);
  // Scale bar, bottom right.
  const double bar_mm = NiceStep(layout.pixels_per_mm, 60.0);
  const int bar_px = cvRound(bar_mm * layout.pixels_per_mm);
  const int bx1 = layout.image_width - 24, bx0 = bx1 - bar_px, by = layout.image_height - 20;
  cv::rectangle(canvas, cv::Point(bx0, by - 4), cv::Point(bx1, by), kText, cv::FILLED);
  const std::string bar_label = Fmt(bar_mm < 1.0 ? "%.1f mm" : "%.0f mm", bar_mm);
  PutText(canvas, bar_label, {bx0 + (bar_px - TextWidth(bar_label)) / 2, by - 10}, kText);

  if (png.has_parent_path()) std::filesystem::create_directories(png.parent_path());
  assert(canvas.type() == CV_8UC3 && canvas.isContinuous());
  cv::Mat rgb;
  cv::cvtColor(canvas, rgb, cv::COLOR_BGR2RGB);
  RgbImage image;
  image.width = rgb.cols;
  image.height = rgb.rows;
  image.rgb.assign(rgb.data, rgb.data + rgb.total() * 3);
  WritePngRgb(png, image);
}

Volume MakeRenderPhantom(const PhantomSpec& spec) {
  VolumeGeometry g;
  g.dims = spec.dims;
  g.spacing_mm = spec.spacing_mm;
  g.origin_mm = spec.origin_mm;
  Volume v = Volume::Create(g, 20);
  const Eigen::Vector3d a = spec.line_from_mm, b = spec.line_to_mm;
  const double len2 = std::max((b - a).squaredNorm(), 1e-12);
  for (int k = 0; k < g.dims.z(); ++k) {
    for (int j = 0; j < g.dims.y(); ++j) {
      for (int i = 0; i < g.dims.x(); ++i) {
        const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(i, j, k));
        const double t = std::clamp((p - a).dot(b - a) / len2, 0.0, 1.0);
        if ((p - (a + t * (b - a))).norm() <= 1.0) {
          v.at(i, j, k) = 230;
        } else if ((p - spec.sphere_centre_mm).norm() <= spec.sphere_radius_mm) {
          v.at(i, j, k) = 200;
        }
      }
    }
  }
  return v;
}

}  // namespace echoservo::imaging
