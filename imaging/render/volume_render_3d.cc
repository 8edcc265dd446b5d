// The 3D isosurface view (VTK, offscreen). VTK 9.1 on this platform has neither OSMesa nor
// EGL, so its offscreen window still needs an X server, and without one it aborts the
// process: XDisplayAvailable() is checked before any render window is created.
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkColorTransferFunction.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkLineSource.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkOutlineSource.h>
#include <vtkPNGWriter.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkSmartVolumeMapper.h>
#include <vtkSphereSource.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkTubeFilter.h>
#include <vtkUnsignedCharArray.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>
#include <vtkWindowToImageFilter.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include "imaging/render/render_overlays_check.h"
#include "imaging/render/volume_render.h"

namespace echoservo::imaging {
namespace {

// Index-scaled grid (origin 0, spacing) whose actors get the direction + origin as their
// user matrix, so any direction matrix renders correctly.
vtkSmartPointer<vtkImageData> ToImageData(const Volume& volume) {
  auto image = vtkSmartPointer<vtkImageData>::New();
  const Eigen::Vector3i& d = volume.dims();
  image->SetDimensions(d.x(), d.y(), d.z());
  image->SetSpacing(volume.spacing_mm().data());
  image->SetOrigin(0.0, 0.0, 0.0);
  image->AllocateScalars(VTK_UNSIGNED_CHAR, 1);
  auto* dst = static_cast<std::uint8_t*>(image->GetScalarPointer());
  const auto src = volume.voxels();
  std::memcpy(dst, src.data(), src.size());
  return image;
}

vtkSmartPointer<vtkMatrix4x4> ImageToFrame(const Volume& volume) {
  auto m = vtkSmartPointer<vtkMatrix4x4>::New();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m->SetElement(r, c, volume.direction()(r, c));
    m->SetElement(r, 3, volume.origin_mm()[r]);
  }
  return m;
}

void AddSphere(vtkRenderer* renderer, const Eigen::Vector3d& centre, double radius,
               const double rgb[3], double opacity, bool wireframe) {
  vtkNew<vtkSphereSource> sphere;
  sphere->SetCenter(centre.data());
  sphere->SetRadius(radius);
  sphere->SetThetaResolution(24);
  sphere->SetPhiResolution(16);
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputConnection(sphere->GetOutputPort());
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(rgb[0], rgb[1], rgb[2]);
  actor->GetProperty()->SetOpacity(opacity);
  if (wireframe) actor->GetProperty()->SetRepresentationToWireframe();
  renderer->AddActor(actor);
}

// The line p + t·dir clipped to the axis-aligned box `bounds` (xmin, xmax, ymin, ...);
// false when it misses the box.
bool ClipToBox(const Eigen::Vector3d& p, const Eigen::Vector3d& dir, const double bounds[6],
               Eigen::Vector3d* a, Eigen::Vector3d* b) {
  double t0 = -1e300, t1 = 1e300;
  for (int i = 0; i < 3; ++i) {
    const double lo = bounds[2 * i], hi = bounds[2 * i + 1];
    if (std::abs(dir[i]) < 1e-12) {
      if (p[i] < lo || p[i] > hi) return false;
      continue;
    }
    double ta = (lo - p[i]) / dir[i], tb = (hi - p[i]) / dir[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 <= t1)) return false;
  *a = p + t0 * dir;
  *b = p + t1 * dir;
  return true;
}

// The axis inside the volume's bounding box (image frame).
void AddAxis(vtkRenderer* renderer, const Eigen::Vector3d& p, const Eigen::Vector3d& dir,
             const double frame_bounds[6], double radius, const double rgb[3], double opacity) {
  Eigen::Vector3d a, b;
  if (!ClipToBox(p, dir, frame_bounds, &a, &b)) return;
  vtkNew<vtkLineSource> line;
  line->SetPoint1(a.data());
  line->SetPoint2(b.data());
  vtkNew<vtkTubeFilter> tube;
  tube->SetInputConnection(line->GetOutputPort());
  tube->SetRadius(radius);
  tube->SetNumberOfSides(12);
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputConnection(tube->GetOutputPort());
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(rgb[0], rgb[1], rgb[2]);
  actor->GetProperty()->SetOpacity(opacity);
  renderer->AddActor(actor);
}

std::string FmtPoint(const char* name, const Eigen::Vector3d& p) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%s (%.1f, %.1f, %.1f) mm", name, p.x(), p.y(), p.z());
  return buf;
}

}  // namespace

void RenderIsosurfacePng(const Volume& volume, double iso_level, const RenderOverlays& overlays,
                         const std::filesystem::path& png, const IsosurfaceOptions& options) {
  if (!std::isfinite(iso_level)) {
    throw std::invalid_argument("isosurface: iso level is not finite");
  }
  if (options.width < 16 || options.height < 16 || options.width > 8192 || options.height > 8192) {
    throw std::invalid_argument("isosurface: image size must be 16..8192 px");
  }
  CheckOverlays(overlays);
  std::string why;
  if (!XDisplayAvailable(&why)) {
    throw std::runtime_error(
        std::string("--3d needs an X server (").append(why).append("); run under xvfb-run -a"));
  }

  vtkSmartPointer<vtkImageData> image = ToImageData(volume);
  vtkSmartPointer<vtkMatrix4x4> to_frame = ImageToFrame(volume);
  vtkNew<vtkRenderer> renderer;
  renderer->SetBackground(0.11, 0.12, 0.14);
  renderer->SetBackground2(0.30, 0.32, 0.36);
  renderer->GradientBackgroundOn();

  vtkNew<vtkFlyingEdges3D> iso;
  iso->SetInputData(image);
  iso->SetValue(0, iso_level);
  iso->ComputeNormalsOn();
  iso->Update();
  vtkNew<vtkPolyDataMapper> iso_mapper;
  iso_mapper->SetInputConnection(iso->GetOutputPort());
  iso_mapper->ScalarVisibilityOff();
  vtkNew<vtkActor> iso_actor;
  iso_actor->SetMapper(iso_mapper);
  iso_actor->SetUserMatrix(to_frame);
  iso_actor->GetProperty()->SetColor(0.93, 0.86, 0.74);
  iso_actor->GetProperty()->SetSpecular(0.3);
  iso_actor->GetProperty()->SetSpecularPower(20);
  // See-through when there are markers that may lie inside the surface (the target).
  if (overlays.target_mm || overlays.truth) iso_actor->GetProperty()->SetOpacity(0.55);
  renderer->AddActor(iso_actor);

  vtkNew<vtkOutlineSource> outline;
  double bounds[6];
  image->GetBounds(bounds);
  outline->SetBounds(bounds);
  vtkNew<vtkPolyDataMapper> outline_mapper;
  outline_mapper->SetInputConnection(outline->GetOutputPort());
  vtkNew<vtkActor> outline_actor;
  outline_actor->SetMapper(outline_mapper);
  outline_actor->SetUserMatrix(to_frame);
  outline_actor->GetProperty()->SetColor(0.7, 0.7, 0.7);
  renderer->AddActor(outline_actor);

  // Everything optional below lives here so it outlives the render.
  vtkNew<vtkSmartVolumeMapper> volume_mapper;
  vtkNew<vtkVolume> volume_actor;
  if (options.volume_rendering) {
    volume_mapper->SetInputData(image);
    volume_mapper->SetRequestedRenderModeToRayCast();  // CPU: works under Xvfb
    vtkNew<vtkPiecewiseFunction> opacity;
    opacity->AddPoint(0, 0.0);
    opacity->AddPoint(std::max(1.0, iso_level * 0.5), 0.0);
    opacity->AddPoint(255, 0.25);
    vtkNew<vtkColorTransferFunction> colour;
    colour->AddRGBPoint(0, 0.0, 0.0, 0.0);
    colour->AddRGBPoint(255, 1.0, 0.9, 0.75);
    vtkNew<vtkVolumeProperty> property;
    property->SetScalarOpacity(opacity);
    property->SetColor(colour);
    property->SetInterpolationTypeToLinear();
    volume_actor->SetMapper(volume_mapper);
    volume_actor->SetProperty(property);
    volume_actor->SetUserMatrix(to_frame);
    renderer->AddVolume(volume_actor);
  }

  const double extent = volume.dims().cast<double>().cwiseProduct(volume.spacing_mm()).norm();
  const double marker_r = std::max(0.8, 0.03 * extent);
  // The voxel box in the image frame (its 8 corners mapped), for clipping the axes.
  double frame_bounds[6] = {1e300, -1e300, 1e300, -1e300, 1e300, -1e300};
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner(bounds[(c & 1) ? 1 : 0], bounds[(c & 2) ? 3 : 2],
                                 bounds[(c & 4) ? 5 : 4]);
    const Eigen::Vector3d q = volume.origin_mm() + volume.direction() * corner;
    for (int i = 0; i < 3; ++i) {
      frame_bounds[2 * i] = std::min(frame_bounds[2 * i], q[i]);
      frame_bounds[2 * i + 1] = std::max(frame_bounds[2 * i + 1], q[i]);
    }
  }
  const double red[3] = {1.0, 0.25, 0.25}, green[3] = {0.3, 0.9, 0.3}, yellow[3] = {1.0, 0.86, 0.0},
               cyan[3] = {0.0, 0.9, 1.0};
  if (overlays.axis_point_mm && overlays.axis_direction) {
    AddAxis(renderer, *overlays.axis_point_mm, *overlays.axis_direction, frame_bounds,
            marker_r * 0.3, yellow, 0.8);
  }
  if (overlays.tip_mm) AddSphere(renderer, *overlays.tip_mm, marker_r, red, 1.0, false);
  if (overlays.target_mm) AddSphere(renderer, *overlays.target_mm, marker_r, green, 1.0, false);
  if (overlays.truth) {
    const FrameGroundTruth& t = *overlays.truth;
    if (t.catheter_visible) {
      if (t.axis_direction.norm() > 1e-12) {
        AddAxis(renderer, t.axis_point_mm, t.axis_direction, frame_bounds, marker_r * 0.2, cyan,
                0.6);
      }
      AddSphere(renderer, t.tip_mm, marker_r * 1.4, cyan, 1.0, true);
    }
    if (t.target_visible) AddSphere(renderer, t.target_mm, marker_r * 1.4, cyan, 1.0, true);
  }

  std::string caption =
      overlays.title.empty() ? std::string("echoservo render --3d") : overlays.title;
  char line[160];
  std::snprintf(line, sizeof line, "\nisosurface at %.0f; box %.1f x %.1f x %.1f mm", iso_level,
                bounds[1] - bounds[0], bounds[3] - bounds[2], bounds[5] - bounds[4]);
  caption += line;
  if (overlays.tip_mm) caption.append("\n").append(FmtPoint("tip (red)", *overlays.tip_mm));
  if (overlays.target_mm)
    caption.append("\n").append(FmtPoint("target (green)", *overlays.target_mm));
  if (overlays.axis_point_mm) caption += "\naxis: yellow";
  if (overlays.truth) caption += "\nground truth: cyan";
  vtkNew<vtkTextActor> text;
  text->SetInput(caption.c_str());
  text->GetTextProperty()->SetFontSize(16);
  text->GetTextProperty()->SetColor(0.95, 0.95, 0.95);
  text->SetDisplayPosition(12, 12);
  renderer->AddActor2D(text);

  vtkCamera* camera = renderer->GetActiveCamera();
  camera->SetViewUp(0.0, -1.0, 0.0);  // y down, as in the 2D panels
  camera->Azimuth(35.0);
  camera->Elevation(25.0);
  camera->OrthogonalizeViewUp();
  renderer->ResetCamera(frame_bounds);  // frame the volume, not the glyphs
  camera->Zoom(1.3);
  renderer->ResetCameraClippingRange();

  vtkNew<vtkRenderWindow> window;
  window->SetOffScreenRendering(1);
  window->SetSize(options.width, options.height);
  window->AddRenderer(renderer);
  window->Render();

  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff();
  grab->Update();
  if (png.has_parent_path()) std::filesystem::create_directories(png.parent_path());
  vtkNew<vtkPNGWriter> writer;
  writer->SetFileName(png.string().c_str());
  writer->SetInputConnection(grab->GetOutputPort());
  writer->Write();
  if (writer->GetErrorCode() != 0 || !std::filesystem::exists(png)) {
    throw std::runtime_error("cannot write " + png.string());
  }
}

}  // namespace echoservo::imaging
