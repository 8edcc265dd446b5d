#include "tracking/independent_volumes.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::tracking {
namespace {

// One straight echo (a line segment) with its amplitude, grid frame (mm).
struct Segment {
  Eigen::Vector3d a, b;
  double amplitude;
  double lateral_psf_mm;  // σ across the beam at the segment's range
};

// Amplitude at x of segment `g` blurred by the Gaussian PSF of inverse covariance `P`
// (normalised so that a long segment peaks at its amplitude): the PSF integrated along the
// segment is a Gaussian across it times the difference of two normal CDFs along it.
double BlurredSegment(const Segment& g, const Eigen::Vector3d& x, const Eigen::Matrix3d& P) {
  const Eigen::Vector3d u = g.b - g.a;
  const double len = u.norm();
  if (len < 1e-9) return 0.0;
  const Eigen::Vector3d d = u / len;
  const Eigen::Vector3d r = x - g.a;
  const double dPd = d.dot(P * d);
  const double mu = d.dot(P * r) / dPd;  // along the segment, mm from a
  const double q = r.dot(P * r) - mu * mu * dPd;
  if (q > 50) return 0.0;
  const double sigma_s = 1.0 / std::sqrt(dPd);
  auto Phi = [](double z) { return 0.5 * std::erfc(-z / std::numbers::sqrt2); };
  return g.amplitude * std::exp(-0.5 * q) * (Phi((len - mu) / sigma_s) - Phi(-mu / sigma_s));
}

// Unit-energy Gaussian kernel of σ sigma_vox (voxels), half-width ⌈3σ⌉ (≥ 1).
std::vector<double> UnitEnergyKernel(double sigma_vox) {
  const int half = std::max(1, static_cast<int>(std::ceil(3 * sigma_vox)));
  std::vector<double> k(static_cast<std::size_t>(2 * half + 1));
  double energy = 0;
  for (int t = -half; t <= half; ++t) {
    const double w = std::exp(-0.5 * t * t / (sigma_vox * sigma_vox));
    k[static_cast<std::size_t>(t + half)] = w;
    energy += w * w;
  }
  for (auto& w : k) w /= std::sqrt(energy);
  return k;
}

// Separable Gaussian smoothing of a complex field along one grid axis; the kernel's weights
// have unit energy, so unit-variance white noise stays unit-variance. Along axes 0 and 1 (in
// a plane k) σ is sigma_by_plane[k] (voxels), along axis 2 sigma_by_plane[0].
void SmoothAxis(std::vector<float>& re, std::vector<float>& im, int n, int axis,
                const std::vector<double>& sigma_by_plane) {
  std::vector<std::vector<double>> kernels;  // per distinct σ, in plane order
  std::vector<std::size_t> kernel_of(static_cast<std::size_t>(n), 0);
  for (int p = 0; p < n; ++p) {
    const double sg = sigma_by_plane[axis == 2 ? 0 : static_cast<std::size_t>(p)];
    if (p == 0 || sg != sigma_by_plane[axis == 2 ? 0 : static_cast<std::size_t>(p - 1)])
      kernels.push_back(UnitEnergyKernel(sg));
    kernel_of[static_cast<std::size_t>(p)] = kernels.size() - 1;
  }
  const std::ptrdiff_t stride = axis == 0 ? 1 : axis == 1 ? n : static_cast<std::ptrdiff_t>(n) * n;
  std::vector<float> lr(static_cast<std::size_t>(n)), li(static_cast<std::size_t>(n));
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      // The line's first voxel: the two other axes at (a, b).
      std::ptrdiff_t base = 0;
      if (axis == 0)
        base = static_cast<std::ptrdiff_t>(a) * n + static_cast<std::ptrdiff_t>(b) * n * n;
      if (axis == 1) base = a + static_cast<std::ptrdiff_t>(b) * n * n;
      if (axis == 2) base = a + static_cast<std::ptrdiff_t>(b) * n;
      const std::vector<double>& k =
          kernels[kernel_of[axis == 2 ? 0 : static_cast<std::size_t>(b)]];
      const int half = static_cast<int>(k.size() / 2);
      for (int i = 0; i < n; ++i) {
        double sr = 0, si = 0;
        for (int t = -half; t <= half; ++t) {
          const int j = i + t;
          if (j < 0 || j >= n) continue;
          const auto idx = static_cast<std::size_t>(base + j * stride);
          sr += k[static_cast<std::size_t>(t + half)] * re[idx];
          si += k[static_cast<std::size_t>(t + half)] * im[idx];
        }
        lr[static_cast<std::size_t>(i)] = static_cast<float>(sr);
        li[static_cast<std::size_t>(i)] = static_cast<float>(si);
      }
      for (int i = 0; i < n; ++i) {
        const auto idx = static_cast<std::size_t>(base + i * stride);
        re[idx] = lr[static_cast<std::size_t>(i)];
        im[idx] = li[static_cast<std::size_t>(i)];
      }
    }
}

}  // namespace

void IndependentVolumeOptions::Validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("IndependentVolumeOptions: " + f + " " + why);
  };
  if (size_voxels < 32 || size_voxels > 256) bad("size_voxels", "must be in [32, 256]");
  if (!(voxel_mm > 0 && voxel_mm <= 2)) bad("voxel_mm", "must be in (0, 2]");
  if (!(catheter_angle_deg >= 0 && catheter_angle_deg <= 90))
    bad("catheter_angle_deg", "must be in [0, 90]");
  if (!std::isfinite(catheter_azimuth_deg)) bad("catheter_azimuth_deg", "must be finite");
  if (!(std::abs(advance_mm) < 0.9 * target_gap_mm))
    bad("advance_mm", "must be finite and short of the tissue (|advance| < 0.9 target_gap_mm)");
  if (!tip_offset_mm.allFinite()) bad("tip_offset_mm", "must be finite");
  if (!(apex_distance_mm > 0 && apex_distance_mm < 1000))
    bad("apex_distance_mm", "must be in (0, 1000)");
  if (!beam_direction.allFinite() || !(beam_direction.norm() > 1e-9))
    bad("beam_direction", "must be finite and non-zero");
  if (parallel_beam && store_image_to_probe)
    bad("store_image_to_probe",
        "cannot describe parallel beams (an image-to-probe pose has an apex)");
  if (!(sheath_diameter_mm > 0 && sheath_diameter_mm < 10))
    bad("sheath_diameter_mm", "must be in (0, 10)");
  if (!(wire_diameter_mm >= 0 && wire_diameter_mm <= sheath_diameter_mm))
    bad("wire_diameter_mm", "must be in [0, sheath_diameter_mm]");
  if (!(wire_protrusion_mm >= 0 && wire_protrusion_mm < 50))
    bad("wire_protrusion_mm", "must be in [0, 50)");
  for (double a : {sheath_amplitude, wire_amplitude, far_wall_amplitude})
    if (!(a >= 0 && a <= 10)) bad("amplitudes", "must be in [0, 10]");
  if (!(axial_psf_mm > 0 && axial_psf_mm < 5)) bad("axial_psf_mm", "must be in (0, 5)");
  if (!(lateral_psf_mm > 0 && lateral_psf_mm < 5)) bad("lateral_psf_mm", "must be in (0, 5)");
  if (!(reverb_spacing_mm > 0 && reverb_spacing_mm < 20))
    bad("reverb_spacing_mm", "must be in (0, 20)");
  if (!(reverb_decay >= 0 && reverb_decay < 1)) bad("reverb_decay", "must be in [0, 1)");
  if (reverb_copies < 0 || reverb_copies > 20) bad("reverb_copies", "must be in [0, 20]");
  if (!(shadow >= 0 && shadow <= 1)) bad("shadow", "must be in [0, 1]");
  if (!(blood_scatter >= 0 && blood_scatter < 1)) bad("blood_scatter", "must be in [0, 1)");
  if (!(tissue_scatter >= 0 && tissue_scatter < 1)) bad("tissue_scatter", "must be in [0, 1)");
  if (!(target_gap_mm > 0 && target_gap_mm < 100)) bad("target_gap_mm", "must be in (0, 100)");
  if (!(dynamic_range_db > 0 && dynamic_range_db <= 120))
    bad("dynamic_range_db", "must be in (0, 120]");
  if (!(attenuation_db_per_mm >= 0 && attenuation_db_per_mm < 2))
    bad("attenuation_db_per_mm", "must be in [0, 2)");
  if (!(tgc_db_per_mm >= 0 && tgc_db_per_mm < 2)) bad("tgc_db_per_mm", "must be in [0, 2)");
  if (!(gain_reference_mm > 0 && gain_reference_mm < 1000))
    bad("gain_reference_mm", "must be in (0, 1000)");
  if (!(noise_amplitude >= 0 && noise_amplitude < 1)) bad("noise_amplitude", "must be in [0, 1)");
  for (double w : {specular_width_deg, wire_specular_width_deg})
    if (!(w >= 0 && w <= 90)) bad("specular widths", "must be in [0, 90]");
  for (double f : {specular_diffuse, wire_specular_diffuse})
    if (!(f >= 0 && f <= 1)) bad("specular diffuse parts", "must be in [0, 1]");
  if (!(lateral_focus_mm == 0 || (lateral_focus_mm > 0 && lateral_focus_mm < 1000)))
    bad("lateral_focus_mm", "must be 0 or in (0, 1000)");
}

IndependentVolume MakeIndependentVolume(const IndependentVolumeOptions& o) {
  o.Validate();
  const int n = o.size_voxels;
  const double h = o.voxel_mm;
  const double side = (n - 1) * h;
  const Eigen::Vector3d centre = Eigen::Vector3d::Constant(0.5 * side);
  const Eigen::Vector3d apex(0.5 * side, 0.5 * side, -o.apex_distance_mm);
  auto beam_at = [&](const Eigen::Vector3d& q) -> Eigen::Vector3d {
    if (o.parallel_beam) return Eigen::Vector3d::UnitZ();
    return (q - apex).normalized();
  };
  // Range from the transducer, and the lateral PSF there.
  auto range_at = [&](const Eigen::Vector3d& q) {
    return o.parallel_beam ? o.apex_distance_mm + q.z() : (q - apex).norm();
  };
  auto lateral_psf_at = [&](double r) {
    return o.lateral_focus_mm > 0 ? o.lateral_psf_mm * std::max(1.0, r / o.lateral_focus_mm)
                                  : o.lateral_psf_mm;
  };

  // The catheter: the tip at the grid centre (plus offset); its direction makes the given angle
  // with the beam there, the tip towards the transducer or away from it.
  const Eigen::Vector3d tip0 = centre + o.tip_offset_mm;
  const Eigen::Vector3d b_tip = beam_at(tip0);
  Eigen::Vector3d e1 = b_tip.cross(Eigen::Vector3d::UnitY());
  if (e1.norm() < 1e-6) e1 = b_tip.cross(Eigen::Vector3d::UnitX());
  e1.normalize();
  const Eigen::Vector3d e2 = b_tip.cross(e1).normalized();
  const double th = o.catheter_angle_deg * std::numbers::pi / 180;
  const double az = o.catheter_azimuth_deg * std::numbers::pi / 180;
  const Eigen::Vector3d d = ((o.tip_towards_probe ? -1.0 : 1.0) * std::cos(th) * b_tip +
                             std::sin(th) * (std::cos(az) * e1 + std::sin(az) * e2))
                                .normalized();
  const Eigen::Vector3d tip = tip0 + o.advance_mm * d;
  const Eigen::Vector3d target = tip0 + o.target_gap_mm * d;  // the tissue does not move
  const Eigen::Vector3d sheath_end = tip - o.wire_protrusion_mm * d;
  // The shaft runs out of the grid (and the reach of its comet tails): from the tip back to
  // where it leaves the grid grown by that reach.
  const double margin = o.reverb_copies * o.reverb_spacing_mm + 3.0;
  double entry_s = -o.wire_protrusion_mm;
  while (entry_s > -4.0 * side) {
    const Eigen::Vector3d p = tip + (entry_s - 2.0) * d;
    if ((p.array() < -margin).any() || (p.array() > side + margin).any()) break;
    entry_s -= 2.0;
  }
  entry_s -= 2.0;

  // Near-wall direction at an axis point: towards the transducer, ⟂ the axis.
  auto near_wall = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d {
    const Eigen::Vector3d b = beam_at(p);
    Eigen::Vector3d m = -(b - b.dot(d) * d);
    if (m.norm() < 1e-6) return Eigen::Vector3d::Zero();  // along the beam: no near side
    return m.normalized();
  };
  // Echo segments: sheath near wall (and far wall) and wire near wall in 2 mm pieces (the
  // near side turns with the beam), each with its comet tail.
  std::vector<Segment> segments;
  const double R = 0.5 * o.sheath_diameter_mm, rho = 0.5 * o.wire_diameter_mm;
  // Specular fall-off of a wall echo with the angle of incidence ψ (the beam against the
  // wall's normal ⟂ the axis: sin ψ = |b·d|).
  auto specular = [&](const Eigen::Vector3d& b, double width_deg, double diffuse) {
    if (width_deg <= 0) return 1.0;
    const double psi = std::asin(std::min(1.0, std::abs(b.dot(d)))) * 180 / std::numbers::pi;
    return diffuse + (1 - diffuse) * std::exp(-0.5 * (psi / width_deg) * (psi / width_deg));
  };
  auto add_piece = [&](double s0, double s1, double radius, double amp, bool tail, bool wire) {
    const Eigen::Vector3d a = tip + s0 * d, b = tip + s1 * d;
    const Eigen::Vector3d mid = 0.5 * (a + b);
    const Eigen::Vector3d m = near_wall(mid);
    const Eigen::Vector3d bm = beam_at(mid);
    const double psf = lateral_psf_at(range_at(mid));
    amp *= wire ? specular(bm, o.wire_specular_width_deg, o.wire_specular_diffuse)
                : specular(bm, o.specular_width_deg, o.specular_diffuse);
    segments.push_back({a + radius * m, b + radius * m, amp, psf});
    if (!tail) return;
    double ak = amp;
    for (int k = 1; k <= o.reverb_copies; ++k) {
      ak *= o.reverb_decay;
      const Eigen::Vector3d shift = k * o.reverb_spacing_mm * bm;
      segments.push_back({a + radius * m + shift, b + radius * m + shift, ak, psf});
    }
  };
  const double s_sheath = -o.wire_protrusion_mm;
  for (double s = entry_s; s < s_sheath - 1e-9; s += 2.0) {
    const double s1 = std::min(s + 2.0, s_sheath);
    add_piece(s, s1, R, o.sheath_amplitude, true, false);
    add_piece(s, s1, -R, o.far_wall_amplitude, false, false);
  }
  for (double s = s_sheath; s < -1e-9; s += 2.0)
    add_piece(s, std::min(s + 2.0, 0.0), rho, o.wire_amplitude, true, true);
  if (!o.catheter) segments.clear();

  // PSF inverse covariance in the grid frame (beam ≈ grid z; the pyramid's divergence over the
  // volume is neglected in the blur, not in the geometry), σ across the beam as given.
  auto psf_inverse = [&](double lateral) -> Eigen::Matrix3d {
    return Eigen::Vector3d(1 / (lateral * lateral), 1 / (lateral * lateral),
                           1 / (o.axial_psf_mm * o.axial_psf_mm))
        .asDiagonal();
  };
  const Eigen::Matrix3d P = psf_inverse(o.lateral_psf_mm);
  // Interface echo of the tissue surface: σ of the PSF along the surface normal d.
  const double sigma_n = std::sqrt(1.0 / d.dot(P * d));

  // Speckle: white complex Gaussian noise scaled by the local scatter, smoothed by the PSF.
  const std::size_t nv = static_cast<std::size_t>(n) * n * n;
  std::vector<float> re(nv), im(nv);
  std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ull + 12345);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  auto grid_point = [&](int i, int j, int k) { return Eigen::Vector3d(i * h, j * h, k * h); };
  // Shadow: behind the catheter along the beam (the beam back to the transducer passes within
  // R of the shaft).
  auto shadowed = [&](const Eigen::Vector3d& q) {
    const Eigen::Vector3d b = beam_at(q);
    // Closest approach of the ray q − t b (t > 0) and the shaft line tip + s d (s < −protrusion).
    const Eigen::Vector3d w0 = q - sheath_end;
    const double bb = 1, bd = -b.dot(d), dd = 1, wb = -w0.dot(b), wd = w0.dot(d);
    const double den = bb * dd - bd * bd;
    if (den < 1e-6) return false;
    const double t = (bd * wd - dd * wb) / den, s = (bb * wd - bd * wb) / den;
    if (t <= R || s > 0) return false;
    return (q - t * b - (sheath_end + s * d)).norm() < R;
  };
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d q = grid_point(i, j, k);
        double sc = (q - target).dot(d) > 0 ? o.tissue_scatter : o.blood_scatter;
        if (o.catheter && o.shadow < 1 && shadowed(q)) sc *= o.shadow;
        const auto idx = static_cast<std::size_t>(i + n * (j + static_cast<std::ptrdiff_t>(n) * k));
        re[idx] = static_cast<float>(sc) * gauss(rng);
        im[idx] = static_cast<float>(sc) * gauss(rng);
      }
  // Lateral σ per plane k from the range of the plane's centre.
  std::vector<double> lateral_vox(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k)
    lateral_vox[static_cast<std::size_t>(k)] =
        lateral_psf_at(range_at(Eigen::Vector3d(0.5 * side, 0.5 * side, k * h))) / h;
  SmoothAxis(re, im, n, 0, lateral_vox);
  SmoothAxis(re, im, n, 1, lateral_vox);
  SmoothAxis(re, im, n, 2, {o.axial_psf_mm / h});

  // The image frame: the grid's z axis along beam_direction.
  const Eigen::Matrix3d rot =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), o.beam_direction.normalized())
          .toRotationMatrix();
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i::Constant(n);
  g.spacing_mm = Eigen::Vector3d::Constant(h);
  g.origin_mm = Eigen::Vector3d::Zero();
  g.direction = rot;
  imaging::Volume v = imaging::Volume::Create(g);
  const double floor_db = -o.dynamic_range_db;
  // Speckle amplitude, then each echo added (in amplitude) over the voxels near it, then the
  // log compression.
  std::vector<double> amp(nv);
  for (std::size_t i = 0; i < nv; ++i) amp[i] = std::hypot(re[i], im[i]);
  for (const auto& sg : segments) {
    const double reach = 4.0 * std::max(sg.lateral_psf_mm, o.axial_psf_mm) + h;
    const Eigen::Matrix3d Ps = psf_inverse(sg.lateral_psf_mm);
    const Eigen::Vector3d lo = (sg.a.cwiseMin(sg.b).array() - reach) / h,
                          hi = (sg.a.cwiseMax(sg.b).array() + reach) / h;
    const Eigen::Vector3i i0 = lo.array().ceil().cast<int>().max(0),
                          i1 = hi.array().floor().cast<int>().min(n - 1);
    for (int k = i0.z(); k <= i1.z(); ++k)
      for (int j = i0.y(); j <= i1.y(); ++j)
        for (int i = i0.x(); i <= i1.x(); ++i)
          amp[static_cast<std::size_t>(i + n * (j + static_cast<std::ptrdiff_t>(n) * k))] +=
              BlurredSegment(sg, grid_point(i, j, k), Ps);
  }
  // Receiver noise: its own random stream (the speckle stays the same with or without it).
  std::mt19937_64 noise_rng(o.seed * 0xD1B54A32D192ED03ull + 777);
  const bool depth_gain = o.attenuation_db_per_mm > 0 || o.tgc_db_per_mm > 0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d q = grid_point(i, j, k);
        const auto idx = static_cast<std::size_t>(i + n * (j + static_cast<std::ptrdiff_t>(n) * k));
        double a = amp[idx];
        const double zn = (q - target).dot(d) / sigma_n;
        if (std::abs(zn) < 5) a += 3 * o.tissue_scatter * std::exp(-0.5 * zn * zn);
        if (depth_gain || o.noise_amplitude > 0) {
          const double dr = range_at(q) - o.gain_reference_mm;
          a *= std::pow(10.0, (o.tgc_db_per_mm - o.attenuation_db_per_mm) * dr / 20);
          if (o.noise_amplitude > 0) {
            const double g = o.noise_amplitude * std::pow(10.0, o.tgc_db_per_mm * dr / 20);
            const double nr = g * gauss(noise_rng), ni = g * gauss(noise_rng);
            a = std::sqrt(a * a + nr * nr + ni * ni);
          }
        }
        const double db = 20 * std::log10(std::max(a, 1e-12));
        v.voxels()[idx] =
            static_cast<std::uint8_t>(std::clamp(std::lround(255 * (1 - db / floor_db)), 0L, 255L));
      }

  if (o.store_image_to_probe) {
    // Probe frame: origin at the apex, axes the grid's (z along the beam).
    Eigen::Isometry3d image_to_probe = Eigen::Isometry3d::Identity();
    image_to_probe.linear() = rot.transpose();
    image_to_probe.translation() = -apex;
    v.set_image_to_probe(image_to_probe);
  }
  IndependentVolume out{std::move(v), {}, rot * b_tip};
  out.truth.catheter_visible = o.catheter;
  out.truth.axis_point_mm = rot * sheath_end;
  out.truth.axis_direction = rot * d;
  out.truth.tip_mm = rot * tip;
  const Eigen::Vector3d target_idx = target / h;
  out.truth.target_visible = (target_idx.array() >= 0).all() && (target_idx.array() <= n - 1).all();
  out.truth.target_mm = rot * target;
  return out;
}

void SetDeepObliquePhysics(IndependentVolumeOptions& o) {
  o.specular_width_deg = 10;
  o.specular_diffuse = 0.15;
  o.wire_specular_width_deg = 20;
  o.wire_specular_diffuse = 0.3;
  o.attenuation_db_per_mm = 0.3;
  o.tgc_db_per_mm = 0.25;
  o.gain_reference_mm = 60;
  o.noise_amplitude = 0.002;
  o.lateral_focus_mm = 60;
}

void PlaceTipAtDepth(IndependentVolumeOptions& o, double depth_mm) {
  const Eigen::Vector3d& t = o.tip_offset_mm;
  const double lateral2 = t.x() * t.x() + t.y() * t.y();
  const double apex = std::sqrt(std::max(0.0, depth_mm * depth_mm - lateral2)) -
                      0.5 * (o.size_voxels - 1) * o.voxel_mm - t.z();
  if (!(std::isfinite(depth_mm) && depth_mm * depth_mm > lateral2 && apex > 0))
    throw std::invalid_argument("PlaceTipAtDepth: depth_mm " + std::to_string(depth_mm) +
                                " puts the grid above the apex");
  o.apex_distance_mm = apex;
}

}  // namespace echoservo::tracking
