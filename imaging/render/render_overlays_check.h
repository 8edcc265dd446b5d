// Validation of RenderOverlays shared by the 2D and 3D renderers (internal header).
#pragma once

#include <stdexcept>
#include <string>

#include "imaging/render/volume_render.h"

namespace echoservo::imaging {

inline void CheckOverlays(const RenderOverlays& o) {
  auto finite = [](const std::optional<Eigen::Vector3d>& p, const char* name) {
    if (p && !p->allFinite()) {
      throw std::invalid_argument(std::string("render overlays: ") + name + " is not finite");
    }
  };
  finite(o.axis_point_mm, "axis point");
  finite(o.axis_direction, "axis direction");
  finite(o.tip_mm, "tip");
  finite(o.target_mm, "target");
  finite(o.slice_point_mm, "slice point");
  if (o.axis_direction && o.axis_direction->norm() < 1e-12) {
    throw std::invalid_argument("render overlays: axis direction is zero");
  }
  if (o.axis_direction.has_value() != o.axis_point_mm.has_value()) {
    throw std::invalid_argument("render overlays: axis needs both a point and a direction");
  }
  if (o.truth) {
    const FrameGroundTruth& t = *o.truth;
    if (!t.axis_point_mm.allFinite() || !t.axis_direction.allFinite() || !t.tip_mm.allFinite() ||
        !t.target_mm.allFinite()) {
      throw std::invalid_argument("render overlays: ground truth is not finite");
    }
  }
}

}  // namespace echoservo::imaging
