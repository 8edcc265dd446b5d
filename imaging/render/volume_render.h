// Pictures of a volume for people: an orthogonal-slice + maximum-intensity-projection
// panel (OpenCV, works anywhere) and a 3D isosurface view (VTK, needs an X server).
//
// All overlay points are in the volume's image frame (mm, MetaImage physical space, see
// imaging/volume.h), the frame the detectors report in. The 2D panels are drawn along the
// volume's index axes (i → x, j → y, k → z), each voxel shown spacing_mm wide, so
// anisotropic voxels keep their true aspect; with an identity direction matrix the axis
// labels are image-frame coordinates, otherwise millimetres along the index axes from the
// origin voxel.
#pragma once

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include "imaging/ground_truth.h"
#include "imaging/render/x_display.h"
#include "imaging/volume.h"

namespace echoservo::imaging {

// What to draw on top of the volume. Every field is optional; points in mm (image frame).
struct RenderOverlays {
  std::optional<Eigen::Vector3d> axis_point_mm;   // detected catheter axis: a point on it
  std::optional<Eigen::Vector3d> axis_direction;  // … and its direction (any length > 0)
  std::optional<Eigen::Vector3d> tip_mm;          // detected tip
  std::optional<Eigen::Vector3d> target_mm;       // detected target
  std::optional<FrameGroundTruth> truth;          // simulator ground truth (drawn in cyan)
  // Where the three orthogonal slices cross; default: the tip, else the truth tip (when
  // the catheter is visible), else the volume centre. Clamped into the volume.
  std::optional<Eigen::Vector3d> slice_point_mm;
  std::string title;  // first line of the caption (optional)
};

// Layout of the 2D panel image, for callers (and tests) that need to find things in it.
// Panels 0–2: slices normal to z, y, x (planes xy, xz, yz); panels 3–5: the MIPs along
// z, y, x (same planes). In every panel the horizontal axis is the first in-plane index
// axis (x, x, y) and the vertical one the second (y, z, z), increasing downwards.
struct SlicePanelLayout {
  struct Panel {
    int x0 = 0, y0 = 0;  // top-left pixel of the volume image inside the PNG
    int width = 0, height = 0;
    int u_axis = 0, v_axis = 1;  // index axes shown horizontally / vertically
    int normal_axis = 2;         // the axis sliced / projected along
  };
  std::array<Panel, 6> panels;
  double pixels_per_mm = 1.0;
  int image_width = 0, image_height = 0;
  Eigen::Vector3d slice_index = Eigen::Vector3d::Zero();  // voxel index the slices go through
};

// The layout RenderSlicesPng uses for this volume and overlays (no drawing).
SlicePanelLayout ComputeSlicePanelLayout(const Volume& volume, const RenderOverlays& overlays);

// Pixel (x right, y down; sub-pixel) of image-frame point `point_mm` in panel `panel` of
// `layout` (the point is projected along the panel's normal axis). No bounds check.
Eigen::Vector2d ProjectToPanel(const Volume& volume, const SlicePanelLayout& layout, int panel,
                               const Eigen::Vector3d& point_mm);

// Writes the slice/MIP panel as a PNG (parent folders created). Throws std::invalid_argument
// for a non-finite overlay or a zero axis direction, std::runtime_error when the file cannot
// be written.
void RenderSlicesPng(const Volume& volume, const RenderOverlays& overlays,
                     const std::filesystem::path& png);

struct IsosurfaceOptions {
  int width = 900, height = 700;  // PNG size, px
  bool volume_rendering = false;  // add a translucent ray-cast rendering of the voxels
};

// Renders the iso_level isosurface (vtkFlyingEdges3D; iso_level in voxel units 0–255)
// with the overlays as 3D glyphs, offscreen, and writes a PNG. Needs an X server: checks
// XDisplayAvailable() before any VTK window exists and otherwise throws std::runtime_error
// ("--3d needs an X server (...); run under xvfb-run -a"). Throws std::invalid_argument
// for a non-finite iso level or bad overlays.
void RenderIsosurfacePng(const Volume& volume, double iso_level, const RenderOverlays& overlays,
                         const std::filesystem::path& png, const IsosurfaceOptions& options = {});

// A small synthetic volume for demos and tests: dark speckle-free background (value 20),
// a bright (230) straight "catheter" of radius ~1 mm from `line_from_mm` to `line_to_mm`
// and a bright (200) sphere of `sphere_radius_mm` around `sphere_centre_mm`.
struct PhantomSpec {
  Eigen::Vector3i dims{48, 40, 64};
  Eigen::Vector3d spacing_mm{0.5, 0.5, 0.75};
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d line_from_mm{4.0, 5.0, 6.0};
  Eigen::Vector3d line_to_mm{14.0, 12.0, 30.0};
  Eigen::Vector3d sphere_centre_mm{17.0, 10.0, 38.0};
  double sphere_radius_mm = 4.0;
};
Volume MakeRenderPhantom(const PhantomSpec& spec = {});

}  // namespace echoservo::imaging
