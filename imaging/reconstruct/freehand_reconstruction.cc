#include "imaging/reconstruct/freehand_reconstruction.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace echoservo::imaging {
namespace {

constexpr double kRigidTolerance = 1e-3;  // |RᵀR − I| for tracker transforms (float text)

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

bool AllFinite(const Eigen::Matrix4d& m) { return m.allFinite(); }

bool IsRigid(const Eigen::Matrix4d& m) {
  if (!AllFinite(m)) return false;
  if (std::abs(m(3, 0)) > 1e-9 || std::abs(m(3, 1)) > 1e-9 || std::abs(m(3, 2)) > 1e-9 ||
      std::abs(m(3, 3) - 1.0) > 1e-9) {
    return false;
  }
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  return (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < kRigidTolerance;
}

// Inverse of a rigid 4×4 (rotation transposed).
Eigen::Matrix4d RigidInverse(const Eigen::Matrix4d& m) {
  Eigen::Matrix4d inv = Eigen::Matrix4d::Identity();
  const Eigen::Matrix3d rt = m.topLeftCorner<3, 3>().transpose();
  inv.topLeftCorner<3, 3>() = rt;
  inv.topRightCorner<3, 1>() = -rt * m.topRightCorner<3, 1>();
  return inv;
}

std::optional<Eigen::Matrix4d> ParseMatrix16(const std::string& text, const std::string& where) {
  std::istringstream in(text);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!(in >> m(r, c))) {
        throw std::invalid_argument(where + ": expected 16 numbers (row-major 4x4), got '" + text +
                                    "'");
      }
    }
  }
  std::string extra;
  if (in >> extra) {
    throw std::invalid_argument(where + ": more than 16 numbers in '" + text + "'");
  }
  return m;
}

// Why a frame cannot be used, or nullopt with its image-to-output transform set.
enum class Skip { kNone, kImageStatus, kMissing, kStatus, kBad };

struct FramePlacement {
  Skip skip = Skip::kNone;
  Eigen::Matrix4d image_to_output = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d image_to_probe = Eigen::Matrix4d::Identity();
};

// A named transform of a frame: missing / status not OK / unparsable or not rigid.
Skip GetRigid(const SequenceFrame& frame, const std::string& name, Eigen::Matrix4d* out) {
  const std::optional<std::string> status = frame.TransformStatus(name);
  if (!status) return Skip::kMissing;
  if (*status != "OK") return Skip::kStatus;
  std::optional<Eigen::Matrix4d> m;
  try {
    m = frame.Transform(name);
  } catch (const std::invalid_argument&) {
    return Skip::kBad;
  }
  if (!m) return Skip::kMissing;
  if (!IsRigid(*m)) return Skip::kBad;
  *out = *m;
  return Skip::kNone;
}

FramePlacement PlaceFrame(const SequenceFrame& frame, const ReconstructionOptions& options,
                          const std::optional<Eigen::Matrix4d>& fixed_image_to_probe) {
  FramePlacement p;
  const std::optional<std::string> image_status = frame.ImageStatus();
  if (image_status && *image_status != "OK") {
    p.skip = Skip::kImageStatus;
    return p;
  }
  if (fixed_image_to_probe) {
    p.image_to_probe = *fixed_image_to_probe;
  } else {
    const std::optional<std::string> status = frame.TransformStatus("ImageToProbe");
    if (!status) {
      p.skip = Skip::kMissing;
      return p;
    }
    if (*status != "OK") {
      p.skip = Skip::kStatus;
      return p;
    }
    std::optional<Eigen::Matrix4d> m;
    try {
      m = frame.Transform("ImageToProbe");
      if (m) ValidateImageToProbe(*m, "ImageToProbeTransform");
    } catch (const std::invalid_argument&) {
      p.skip = Skip::kBad;
      return p;
    }
    if (!m) {
      p.skip = Skip::kMissing;
      return p;
    }
    p.image_to_probe = *m;
  }
  Eigen::Matrix4d probe_to_tracker;
  p.skip = GetRigid(frame, options.probe_tool + "ToTracker", &probe_to_tracker);
  if (p.skip != Skip::kNone) return p;
  Eigen::Matrix4d tracker_to_output = Eigen::Matrix4d::Identity();
  if (!options.reference_tool.empty()) {
    Eigen::Matrix4d reference_to_tracker;
    p.skip = GetRigid(frame, options.reference_tool + "ToTracker", &reference_to_tracker);
    if (p.skip != Skip::kNone) return p;
    tracker_to_output = RigidInverse(reference_to_tracker);
  }
  p.image_to_output = tracker_to_output * probe_to_tracker * p.image_to_probe;
  if (!AllFinite(p.image_to_output)) p.skip = Skip::kBad;
  return p;
}

// The calibration given once for all frames (option or header), with where it came from;
// nullopt when the frames must carry it.
std::optional<Eigen::Matrix4d> FixedCalibration(const PlusSequence& sequence,
                                                const ReconstructionOptions& options,
                                                std::string* source) {
  if (options.image_to_probe) {
    ValidateImageToProbe(*options.image_to_probe, "image-to-probe option");
    *source = "option";
    return options.image_to_probe;
  }
  bool any_frame_field = false;
  for (const SequenceFrame& f : sequence.frames) {
    if (f.TransformStatus("ImageToProbe")) {
      any_frame_field = true;
      break;
    }
  }
  if (any_frame_field) {
    *source = "frame field ImageToProbeTransform";
    return std::nullopt;
  }
  for (const char* key : {"ImageToProbeTransform", "ImageToProbe"}) {
    if (const std::optional<std::string> text = sequence.HeaderField(key)) {
      const std::string where = std::string("header field ") + key;
      std::optional<Eigen::Matrix4d> m = ParseMatrix16(*text, where);
      ValidateImageToProbe(*m, where);
      *source = where;
      return m;
    }
  }
  throw std::invalid_argument(
      "no image-to-probe calibration: the sequence has no ImageToProbeTransform frame field or "
      "header field; give one (16 numbers, row-major, mm per pixel included) as an option");
}

void ValidateOptions(const ReconstructionOptions& o) {
  if (!std::isfinite(o.spacing_mm) || o.spacing_mm <= 0.0) {
    throw std::invalid_argument("reconstruction spacing must be finite and > 0 mm, got " +
                                Num(o.spacing_mm));
  }
  if (o.roi_mm) {
    if (!o.roi_mm->min().allFinite() || !o.roi_mm->max().allFinite() ||
        (o.roi_mm->max().array() <= o.roi_mm->min().array()).any()) {
      throw std::invalid_argument(
          "reconstruction region of interest must be finite with max > min on every axis");
    }
  }
  if (o.probe_tool.empty()) throw std::invalid_argument("reconstruction probe tool name is empty");
  if (o.hole_fill_radius_voxels < 1 || o.hole_fill_radius_voxels > 5) {
    throw std::invalid_argument("hole-filling radius must be 1..5 voxels, got " +
                                std::to_string(o.hole_fill_radius_voxels));
  }
  if (!(o.hole_fill_min_known_ratio > 0.0 && o.hole_fill_min_known_ratio <= 1.0)) {
    throw std::invalid_argument("hole-filling known ratio must be in (0, 1]");
  }
  if (o.max_voxels < 1) throw std::invalid_argument("max voxels must be >= 1");
}

// Empty voxels take the Gaussian-weighted mean (σ = r/1.5 voxels, at least 1) of the known
// voxels in the (2r+1)³ kernel when enough of them are known. Reads only voxels known
// before filling (one pass, no cascading).
std::int64_t FillHoles(const std::vector<float>& weight, Volume* volume, int radius,
                       double min_ratio) {
  const Eigen::Vector3i d = volume->dims();
  const double sigma = std::max(1.0, radius / 1.5);
  struct Tap {
    int dx, dy, dz;
    float w;
  };
  std::vector<Tap> taps;
  for (int z = -radius; z <= radius; ++z) {
    for (int y = -radius; y <= radius; ++y) {
      for (int x = -radius; x <= radius; ++x) {
        if (x == 0 && y == 0 && z == 0) continue;
        taps.push_back(
            {x, y, z,
             static_cast<float>(std::exp(-(x * x + y * y + z * z) / (2.0 * sigma * sigma)))});
      }
    }
  }
  const std::size_t need =
      static_cast<std::size_t>(std::ceil(min_ratio * static_cast<double>(taps.size())));
  const std::vector<std::uint8_t> before(volume->voxels().begin(), volume->voxels().end());
  const std::size_t nx = d.x(), nxy = static_cast<std::size_t>(d.x()) * d.y();
  std::int64_t filled = 0;
  for (int k = 0; k < d.z(); ++k) {
    for (int j = 0; j < d.y(); ++j) {
      for (int i = 0; i < d.x(); ++i) {
        const std::size_t at = i + nx * j + nxy * k;
        if (weight[at] > 0.0f) continue;
        double sum = 0.0, wsum = 0.0;
        std::size_t known = 0;
        for (const Tap& t : taps) {
          const int x = i + t.dx, y = j + t.dy, z = k + t.dz;
          if (x < 0 || y < 0 || z < 0 || x >= d.x() || y >= d.y() || z >= d.z()) continue;
          const std::size_t n = x + nx * y + nxy * z;
          if (weight[n] <= 0.0f) continue;
          ++known;
          sum += t.w * before[n];
          wsum += t.w;
        }
        if (known >= need && wsum > 0.0) {
          volume->voxels()[at] =
              static_cast<std::uint8_t>(std::clamp(std::lround(sum / wsum), 0L, 255L));
          ++filled;
        }
      }
    }
  }
  return filled;
}

}  // namespace

void ValidateImageToProbe(const Eigen::Matrix4d& m, const std::string& where) {
  if (!m.allFinite()) throw std::invalid_argument(where + ": non-finite number in the matrix");
  if (std::abs(m(3, 0)) > 1e-9 || std::abs(m(3, 1)) > 1e-9 || std::abs(m(3, 2)) > 1e-9 ||
      std::abs(m(3, 3) - 1.0) > 1e-9) {
    throw std::invalid_argument(where + ": last row must be 0 0 0 1");
  }
  const double det = m.topLeftCorner<3, 3>().determinant();
  if (!(std::abs(det) > 1e-12)) {
    throw std::invalid_argument(where + ": singular linear part (determinant " + Num(det) + ")");
  }
}

ReconstructionResult ReconstructFreehand(const PlusSequence& sequence,
                                         const ReconstructionOptions& options) {
  ValidateOptions(options);
  if (sequence.volume_frames) {
    throw std::invalid_argument(
        "reconstruct: the sequence holds 3D frames (NDims = 4); freehand reconstruction needs "
        "2D frames");
  }
  if (sequence.FrameBytes() == 0 || sequence.frame_dims[0] < 1 || sequence.frame_dims[1] < 1) {
    throw std::invalid_argument("reconstruct: the sequence has no pixels (tracker-only)");
  }
  if (sequence.element_type != "MET_UCHAR" || sequence.element_size != 1) {
    throw std::invalid_argument("reconstruct: element type " + sequence.element_type +
                                " is not supported (MET_UCHAR only)");
  }
  if (sequence.pixels.size() != sequence.frames.size() * sequence.FrameBytes()) {
    throw std::invalid_argument("reconstruct: pixel data does not match the frame count");
  }

  ReconstructionResult result{Volume::Create(VolumeGeometry{}),
                              0,
                              0,
                              0,
                              0,
                              0,
                              0,
                              0,
                              0,
                              0,
                              {},
                              Eigen::Matrix4d::Identity(),
                              options.reference_tool.empty() ? "Tracker" : options.reference_tool};
  const std::optional<Eigen::Matrix4d> fixed =
      FixedCalibration(sequence, options, &result.calibration_source);

  // Place every frame; count the skipped ones by reason.
  const std::size_t n = sequence.frames.size();
  result.frames_total = n;
  std::vector<std::size_t> used;
  std::vector<Eigen::Matrix4d> image_to_output;
  for (std::size_t f = 0; f < n; ++f) {
    const FramePlacement p = PlaceFrame(sequence.frames[f], options, fixed);
    switch (p.skip) {
      case Skip::kImageStatus:
        ++result.skipped_image_status;
        continue;
      case Skip::kMissing:
        ++result.skipped_missing_transform;
        continue;
      case Skip::kStatus:
        ++result.skipped_invalid_status;
        continue;
      case Skip::kBad:
        ++result.skipped_bad_transform;
        continue;
      case Skip::kNone:
        break;
    }
    if (used.empty()) result.image_to_probe = p.image_to_probe;
    used.push_back(f);
    image_to_output.push_back(p.image_to_output);
  }
  result.frames_used = used.size();
  if (used.empty()) {
    std::ostringstream s;
    s << "reconstruct: no usable frame among " << n
      << " (ImageStatus not OK: " << result.skipped_image_status
      << ", transform missing: " << result.skipped_missing_transform
      << ", transform status not OK: " << result.skipped_invalid_status
      << ", transform non-finite or not rigid: " << result.skipped_bad_transform << "; probe tool '"
      << options.probe_tool << "'"
      << (options.reference_tool.empty() ? "" : ", reference tool '" + options.reference_tool + "'")
      << ")";
    throw std::invalid_argument(s.str());
  }

  // Output region: the ROI or the bounding box of the used frames' corner pixels.
  const int w = sequence.frame_dims[0], h = sequence.frame_dims[1];
  Eigen::AlignedBox3d box;
  if (options.roi_mm) {
    box = *options.roi_mm;
  } else {
    for (const Eigen::Matrix4d& m : image_to_output) {
      for (const double ci : {0.0, static_cast<double>(w - 1)}) {
        for (const double cj : {0.0, static_cast<double>(h - 1)}) {
          box.extend((m * Eigen::Vector4d(ci, cj, 0.0, 1.0)).head<3>());
        }
      }
    }
  }
  const double s = options.spacing_mm;
  Eigen::Array3d extent = (box.max() - box.min()).array() / s;
  std::array<std::int64_t, 3> dims{};
  for (int a = 0; a < 3; ++a) {
    const double cells = std::floor(extent[a] + 1e-9) + 1.0;
    if (!std::isfinite(cells) || cells > 1e12) {
      throw std::invalid_argument("reconstruct: the region is too large (" + Num(extent[a] * s) +
                                  " mm along an axis)");
    }
    dims[a] = static_cast<std::int64_t>(cells);
  }
  const double voxels = static_cast<double>(dims[0]) * dims[1] * dims[2];
  if (voxels > static_cast<double>(options.max_voxels) ||
      voxels > static_cast<double>(VolumeGeometry::kMaxVoxels) ||
      std::max({dims[0], dims[1], dims[2]}) > VolumeGeometry::kMaxDim) {
    std::ostringstream msg;
    msg << "reconstruct: the region " << Num((box.max() - box.min()).x()) << " x "
        << Num((box.max() - box.min()).y()) << " x " << Num((box.max() - box.min()).z())
        << " mm at " << Num(s) << " mm needs " << dims[0] << " x " << dims[1] << " x " << dims[2]
        << " = " << Num(voxels) << " voxels, more than the limit of "
        << std::min<std::int64_t>(options.max_voxels, VolumeGeometry::kMaxVoxels) << " (at most "
        << VolumeGeometry::kMaxDim
        << " per axis); raise the spacing, give a smaller region of interest or raise the "
           "voxel limit";
    throw std::invalid_argument(msg.str());
  }
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(static_cast<int>(dims[0]), static_cast<int>(dims[1]),
                           static_cast<int>(dims[2]));
  g.spacing_mm = Eigen::Vector3d::Constant(s);
  g.origin_mm = box.min();
  Volume volume = Volume::Create(g, 0);

  // Accumulate.
  const std::size_t count = static_cast<std::size_t>(volume.voxel_count());
  std::vector<float> sum(count, 0.0f), weight(count, 0.0f);
  const int nx = g.dims.x(), ny = g.dims.y(), nz = g.dims.z();
  const std::size_t sx = 1, sy = nx, sz = static_cast<std::size_t>(nx) * ny;
  const std::size_t frame_bytes = sequence.FrameBytes();
  for (std::size_t u = 0; u < used.size(); ++u) {
    const std::uint8_t* pixels = sequence.pixels.data() + used[u] * frame_bytes;
    // Image pixel → continuous voxel index of the output volume.
    const Eigen::Matrix4d& m = image_to_output[u];
    const Eigen::Vector3d o = (m.topRightCorner<3, 1>() - box.min()) / s;
    const Eigen::Vector3d di = m.block<3, 1>(0, 0) / s;
    const Eigen::Vector3d dj = m.block<3, 1>(0, 1) / s;
    for (int j = 0; j < h; ++j) {
      const Eigen::Vector3d row = o + dj * j;
      const std::uint8_t* line = pixels + static_cast<std::size_t>(j) * w;
      for (int i = 0; i < w; ++i) {
        Eigen::Vector3d v = row + di * i;
        // The box's own corner pixels may land a rounding error below index 0.
        for (int a = 0; a < 3; ++a) {
          if (v[a] < 0.0 && v[a] > -1e-6) v[a] = 0.0;
        }
        const float value = line[i];
        if (options.compounding == Compounding::kWeighted) {
          const double fx = std::floor(v.x()), fy = std::floor(v.y()), fz = std::floor(v.z());
          // All 8 neighbours must exist for a weight-complete splat, except on the last
          // plane where the fraction is 0 (a pixel exactly on a boundary voxel centre).
          if (!(fx >= 0 && fy >= 0 && fz >= 0 && fx <= nx - 1 && fy <= ny - 1 && fz <= nz - 1)) {
            ++result.pixels_outside;
            continue;
          }
          const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy), z0 = static_cast<int>(fz);
          const float tx = static_cast<float>(v.x() - fx), ty = static_cast<float>(v.y() - fy),
                      tz = static_cast<float>(v.z() - fz);
          const std::size_t base = x0 * sx + y0 * sy + z0 * sz;
          for (int c = 0; c < 8; ++c) {
            const int bx = c & 1, by = (c >> 1) & 1, bz = (c >> 2) & 1;
            const float wgt = (bx ? tx : 1.0f - tx) * (by ? ty : 1.0f - ty) * (bz ? tz : 1.0f - tz);
            if (wgt <= 0.0f) continue;
            if (x0 + bx >= nx || y0 + by >= ny || z0 + bz >= nz) continue;  // weight is ~0 there
            const std::size_t at = base + bx * sx + by * sy + bz * sz;
            sum[at] += wgt * value;
            weight[at] += wgt;
          }
        } else {
          const double rx = std::floor(v.x() + 0.5), ry = std::floor(v.y() + 0.5),
                       rz = std::floor(v.z() + 0.5);
          if (!(rx >= 0 && ry >= 0 && rz >= 0 && rx < nx && ry < ny && rz < nz)) {
            ++result.pixels_outside;
            continue;
          }
          const std::size_t at = static_cast<std::size_t>(rx) * sx +
                                 static_cast<std::size_t>(ry) * sy +
                                 static_cast<std::size_t>(rz) * sz;
          if (options.compounding == Compounding::kNearestLast) {
            sum[at] = value;
            weight[at] = 1.0f;
          } else {
            sum[at] += value;
            weight[at] += 1.0f;
          }
        }
      }
    }
    if (options.progress) options.progress(u + 1, used.size());
  }

  std::span<std::uint8_t> out = volume.voxels();
  for (std::size_t a = 0; a < count; ++a) {
    if (weight[a] > 0.0f) {
      out[a] = static_cast<std::uint8_t>(std::clamp(std::lround(sum[a] / weight[a]), 0L, 255L));
      ++result.voxels_known;
    }
  }
  sum.clear();
  sum.shrink_to_fit();
  if (options.fill_holes) {
    result.voxels_filled_holes = FillHoles(weight, &volume, options.hole_fill_radius_voxels,
                                           options.hole_fill_min_known_ratio);
  }
  result.volume = std::move(volume);
  return result;
}

VolumeAgreement CompareVolumes(const Volume& a, const Volume& b, int max_shift_voxels) {
  if (max_shift_voxels < 0 || max_shift_voxels > 50) {
    throw std::invalid_argument("CompareVolumes: max shift must be 0..50 voxels");
  }
  const Eigen::Vector3d step = a.spacing_mm();
  // Correlation at a shift, on every `stride`-th voxel of a along each axis.
  auto correlate = [&](const Eigen::Vector3i& shift, int stride, std::int64_t* overlap) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    std::int64_t n = 0;
    const Eigen::Vector3d offset = shift.cast<double>().cwiseProduct(step);
    for (int k = 0; k < a.dims().z(); k += stride) {
      for (int j = 0; j < a.dims().y(); j += stride) {
        for (int i = 0; i < a.dims().x(); i += stride) {
          const double va = a.at(i, j, k);
          if (va <= 0) continue;
          const Eigen::Vector3d p = a.IndexToPhysical(Eigen::Vector3d(i, j, k)) + offset;
          const double vb = b.Sample(p);
          if (!(vb > 0)) continue;
          ++n;
          sa += va;
          sb += vb;
          saa += va * va;
          sbb += vb * vb;
          sab += va * vb;
        }
      }
    }
    if (overlap) *overlap = n;
    if (n < 2) return 0.0;
    const double cov = sab - sa * sb / n, va = saa - sa * sa / n, vb = sbb - sb * sb / n;
    return va > 0 && vb > 0 ? cov / std::sqrt(va * vb) : 0.0;
  };
  VolumeAgreement r;
  r.correlation = correlate(Eigen::Vector3i::Zero(), 1, &r.overlap_voxels);
  // Hill climbing over integer shifts (subsampled by 2 for speed), then the winner at full
  // resolution.
  Eigen::Vector3i best = Eigen::Vector3i::Zero();
  double best_c = correlate(best, 2, nullptr);
  for (bool moved = true; moved;) {
    moved = false;
    Eigen::Vector3i cand_best = best;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i c = best + Eigen::Vector3i(dx, dy, dz);
          if (c == best || c.cwiseAbs().maxCoeff() > max_shift_voxels) continue;
          const double v = correlate(c, 2, nullptr);
          if (v > best_c + 1e-9) {
            best_c = v;
            cand_best = c;
            moved = true;
          }
        }
      }
    }
    best = cand_best;
  }
  r.best_shift_mm = best.cast<double>().cwiseProduct(step);
  r.best_correlation =
      best == Eigen::Vector3i::Zero() ? r.correlation : correlate(best, 1, nullptr);
  return r;
}

}  // namespace echoservo::imaging
