#include "imaging/sim/simulated_scanner.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

#if defined(__SSE__) || defined(__x86_64__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#define ECHOSERVO_HAVE_SSE_FTZ 1
#endif

namespace echoservo::imaging::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kMaxHits = 16;
constexpr int kMaxEchoes = 48;
constexpr int kMaxSegments = kMaxHits + 1;
constexpr int kKernelPhases = 16;
constexpr float kSpeckleScale = 48.0f;  // uint8 speckle table value for unit mean amplitude

void EnableFlushToZero() {
#ifdef ECHOSERVO_HAVE_SSE_FTZ
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
}

void RequireScannerRange(double v, double lo, double hi, const std::string& field,
                         bool open_low = false) {
  if (!(std::isfinite(v) && (open_low ? v > lo : v >= lo) && v <= hi)) {
    std::ostringstream os;
    os << "SimulatedScannerOptions: " << field << " must be in " << (open_low ? "(" : "[") << lo
       << ", " << hi << "], got " << v;
    throw std::invalid_argument(os.str());
  }
}

void RequireRigid(const Eigen::Isometry3d& t, const std::string& field) {
  const Eigen::Matrix3d r = t.linear();
  if (!t.matrix().allFinite() || (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      r.determinant() < 0)
    throw std::invalid_argument("SimulatedScannerOptions: " + field +
                                " must be a finite rotation + translation");
}

std::uint64_t SplitMix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Normalised Gaussian taps, centre weight 1 when `peak_one`, else unit sum.
std::vector<float> GaussianTaps(double sigma, bool peak_one) {
  const int r = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<float> w(static_cast<std::size_t>(2 * r + 1));
  double sum = 0;
  for (int k = -r; k <= r; ++k) {
    const double v = std::exp(-0.5 * (k / sigma) * (k / sigma));
    w[static_cast<std::size_t>(k + r)] = static_cast<float>(v);
    sum += v;
  }
  if (!peak_one)
    for (auto& v : w) v = static_cast<float>(v / sum);
  return w;
}

// Wrapped source position of every position and tap of a circular convolution along an
// axis of `len` samples: table[pos · taps + k] = (pos + k − taps / 2) mod len.
std::vector<std::size_t> WrappedTaps(std::size_t len, std::size_t taps) {
  const auto signed_len = static_cast<long long>(len);
  const auto r = static_cast<long long>(taps / 2);
  std::vector<std::size_t> table(len * taps);
  for (std::size_t pos = 0; pos < len; ++pos)
    for (std::size_t k = 0; k < taps; ++k) {
      const long long q = static_cast<long long>(pos + k) - r;
      table[pos * taps + k] = static_cast<std::size_t>((q % signed_len + signed_len) % signed_len);
    }
  return table;
}

// Circular convolution of one contiguous line y = x ⊛ w, taps outermost: the interior of the
// line reads a shifted contiguous run, only the ends go through the wrap table.
void SmoothLine(const float* x, float* y, std::size_t len, const std::vector<float>& w,
                const std::vector<std::size_t>& wrapped) {
  const std::size_t taps = w.size();
  const auto signed_len = static_cast<long long>(len);
  std::fill_n(y, len, 0.0f);
  for (std::size_t k = 0; k < taps; ++k) {
    const float wk = w[k];
    const long long shift = static_cast<long long>(k) - static_cast<long long>(taps / 2);
    // Positions [lo, hi) read x[p + shift] without wrapping.
    const auto lo = static_cast<std::size_t>(std::clamp(-shift, 0ll, signed_len));
    const auto hi = static_cast<std::size_t>(
        std::clamp(signed_len - shift, static_cast<long long>(lo), signed_len));
    for (std::size_t p = 0; p < lo; ++p) y[p] += wk * x[wrapped[p * taps + k]];
    const float* run = x + static_cast<std::size_t>(static_cast<long long>(lo) + shift);
    for (std::size_t p = lo; p < hi; ++p) y[p] += wk * run[p - lo];
    for (std::size_t p = hi; p < len; ++p) y[p] += wk * x[wrapped[p * taps + k]];
  }
}

// One pass of a circular convolution with taps `w` along an axis of `len` samples spaced
// `stride` apart, in a field of n = outer · len · stride floats. Each output is the sum of
// its taps in tap order from zero (the same floats as a direct loop), with no division per
// tap; for stride > 1 the taps run over contiguous rows of `stride` outputs.
void SmoothWrapped(const float* in, float* out, std::size_t n, std::size_t stride, std::size_t len,
                   const std::vector<float>& w) {
  const std::size_t taps = w.size();
  const std::vector<std::size_t> wrapped = WrappedTaps(len, taps);
  if (stride == 1) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n / len, 16),
                      [&](const tbb::blocked_range<std::size_t>& lines) {
                        for (std::size_t l = lines.begin(); l != lines.end(); ++l)
                          SmoothLine(in + l * len, out + l * len, len, w, wrapped);
                      });
    return;
  }
  const std::size_t grain = std::max<std::size_t>(1, (std::size_t{1} << 14) / stride);
  // A row: the `stride` outputs of one (outer, position) pair.
  auto smooth_rows = [&](const tbb::blocked_range<std::size_t>& rows) {
    for (std::size_t row = rows.begin(); row != rows.end(); ++row) {
      const std::size_t pos = row % len;
      const float* base = in + (row - pos) * stride;
      float* dst = out + row * stride;
      std::fill_n(dst, stride, 0.0f);
      for (std::size_t k = 0; k < taps; ++k) {
        const float wk = w[k];
        const float* src = base + wrapped[pos * taps + k] * stride;
        for (std::size_t j = 0; j < stride; ++j) dst[j] += wk * src[j];
      }
    }
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n / stride, grain), smooth_rows);
}

}  // namespace

Eigen::Isometry3d DefaultCatheterBaseToWorld() {
  // +z of the catheter along (cos 10°, 0, sin 10°); the guidewire tip (at 48 mm) lands at
  // (0, 0, 60) in the world.
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(80.0 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d dir = t.linear().col(2);
  t.translation() = Eigen::Vector3d(0, 0, 60) - 48.0 * dir;
  return t;
}

Eigen::Isometry3d DefaultAnnulusToWorld() {
  Eigen::Isometry3d t = DefaultCatheterBaseToWorld();
  t.translation() += (48.0 + 15.0) * t.linear().col(2);
  return t;
}

void SimulatedScannerOptions::Validate() const {
  RequireScannerRange(rate_hz, 0, 200, "rate_hz", true);
  RequireScannerRange(start_time_s, -1e9, 1e9, "start_time_s");
  if (max_frames < -1)
    throw std::invalid_argument("SimulatedScannerOptions: max_frames must be >= -1");
  probe.Validate("SimulatedScannerOptions: probe");
  RequireRigid(probe_to_world, "probe_to_world");
  RequireScannerRange(medium_sound_speed_m_s, 1000, 2000, "medium_sound_speed_m_s");
  RequireScannerRange(assumed_sound_speed_m_s, 1000, 2000, "assumed_sound_speed_m_s");
  RequireScannerRange(frequency_mhz, 0, 20, "frequency_mhz", true);
  RequireScannerRange(attenuation_db_cm_mhz, 0, 5, "attenuation_db_cm_mhz");
  RequireScannerRange(tgc_db_cm_mhz, 0, 5, "tgc_db_cm_mhz");
  RequireScannerRange(gain_db, -60, 60, "gain_db");
  RequireScannerRange(dynamic_range_db, 10, 120, "dynamic_range_db");
  RequireScannerRange(axial_psf_mm, 0, 5, "axial_psf_mm", true);
  RequireScannerRange(lateral_psf_beams, 0, 4, "lateral_psf_beams", true);
  RequireScannerRange(elevation_psf_beams, 0, 4, "elevation_psf_beams", true);
  RequireScannerRange(background_scatter, 0, 1, "background_scatter");
  RequireScannerRange(noise_floor, 0, 1, "noise_floor");
  const auto& c = catheter_geometry;
  RequireScannerRange(c.sheath_diameter_mm, 0, 20, "catheter_geometry.sheath_diameter_mm", true);
  RequireScannerRange(c.sheath_length_mm, 0, 1000, "catheter_geometry.sheath_length_mm", true);
  if (!(std::isfinite(c.wire_diameter_mm) && c.wire_diameter_mm > 0 &&
        c.wire_diameter_mm < c.sheath_diameter_mm))
    throw std::invalid_argument(
        "SimulatedScannerOptions: catheter_geometry.wire_diameter_mm must be in (0, "
        "sheath_diameter_mm)");
  RequireScannerRange(c.wire_protrusion_mm, 0, 200, "catheter_geometry.wire_protrusion_mm");
  const auto& a = annulus_geometry;
  RequireScannerRange(a.diameter_mm, 0, 100, "annulus_geometry.diameter_mm", true);
  RequireScannerRange(a.thickness_mm, 0, 20, "annulus_geometry.thickness_mm", true);
  RequireScannerRange(a.saddle_mm, -a.diameter_mm, a.diameter_mm, "annulus_geometry.saddle_mm");
  RequireRigid(catheter_pose.base_to_world, "catheter_pose.base_to_world");
  RequireScannerRange(catheter_pose.advance_mm, -1000, 1000, "catheter_pose.advance_mm");
  RequireRigid(annulus_to_world, "annulus_to_world");
  if (!(tank_min_mm.allFinite() && tank_max_mm.allFinite() &&
        (tank_max_mm - tank_min_mm).minCoeff() > 0))
    throw std::invalid_argument(
        "SimulatedScannerOptions: tank_max_mm must exceed tank_min_mm on every axis");
  for (std::size_t i = 0; i < extra_meshes.size(); ++i)
    extra_meshes[i].properties.Validate("SimulatedScannerOptions: extra_meshes[" +
                                        std::to_string(i) + "].properties");
}

struct SimulatedScanner::Impl {
  struct Echo {
    float sample;
    float amp;
  };
  struct Segment {
    float sample;  // from this (continuous) sample on
    float level;   // mean speckle amplitude
  };

  explicit Impl(const SimulatedScannerOptions& o)
      : probe(o.probe),
        converter(o.probe),
        depth_scale(o.assumed_sound_speed_m_s / o.medium_sound_speed_m_s) {
    const int nb = probe.beam_count();
    const int ns = probe.n_samples;
    const double dr = probe.sample_spacing_mm();
    world_to_probe = o.probe_to_world.inverse();
    origin_world = o.probe_to_world.translation().cast<float>();
    beam_dirs.resize(static_cast<std::size_t>(nb));
    for (int ie = 0; ie < probe.n_elevation; ++ie)
      for (int ia = 0; ia < probe.n_azimuth; ++ia)
        beam_dirs[static_cast<std::size_t>(ie * probe.n_azimuth + ia)] =
            (o.probe_to_world.linear() * probe.BeamDirection(ia, ie)).cast<float>();
    true_range_mm = static_cast<float>(probe.range_mm / depth_scale);
    samples_per_true_mm = static_cast<float>(depth_scale / dr);

    // Scene.
    if (o.tank)
      tank_id =
          scene.AddMesh(MakeBox(o.tank_min_mm, o.tank_max_mm), AcousticProperties::TankWall());
    const auto& cg = o.catheter_geometry;
    sheath_id = scene.AddMesh(MakeCylinder(0.5 * cg.sheath_diameter_mm, cg.sheath_length_mm, 24),
                              AcousticProperties::Sheath());
    wire_id =
        scene.AddMesh(MakeCylinder(0.5 * cg.wire_diameter_mm, cg.wire_protrusion_mm + 1.0, 16),
                      AcousticProperties::Guidewire());
    if (!o.catheter) {
      scene.SetEnabled(sheath_id, false);
      scene.SetEnabled(wire_id, false);
    }
    const auto& ag = o.annulus_geometry;
    annulus_id = scene.AddMesh(MakeSaddleDisc(ag.diameter_mm, ag.thickness_mm, ag.saddle_mm),
                               AcousticProperties::Tissue(), o.annulus_to_world);
    if (!o.annulus) scene.SetEnabled(annulus_id, false);
    for (const auto& m : o.extra_meshes) scene.AddMesh(m.mesh, m.properties, m.mesh_to_world);
    for (int i = 0; i < scene.mesh_count(); ++i) {
      auto p = scene.properties(i);
      if (!o.reverberation) p.is_metal = false;
      props.push_back(p);
    }

    // Gain per sample: attenuation at the true depth (round trip) × TGC at the displayed
    // depth × master gain.
    gain.resize(static_cast<std::size_t>(ns));
    for (int s = 0; s < ns; ++s) {
      const double r_disp_cm = s * dr / 10.0, r_true_cm = r_disp_cm / depth_scale;
      const double db = -2.0 * o.attenuation_db_cm_mhz * o.frequency_mhz * r_true_cm +
                        2.0 * o.tgc_db_cm_mhz * o.frequency_mhz * r_disp_cm + o.gain_db;
      gain[static_cast<std::size_t>(s)] =
          static_cast<float>(std::pow(10.0, db / 20.0) / kSpeckleScale);
    }
    echo_scale = kSpeckleScale;  // echoes are not speckled: undo the table scale
    noise_level = static_cast<float>(o.noise_floor);

    // Log compression LUT over the upper 16 bits of a float.
    log_lut.resize(1 << 16);
    for (std::uint32_t i = 0; i < (1u << 16); ++i) {
      const std::uint32_t bits = (i << 16) | 0x8000u;
      float v;
      std::memcpy(&v, &bits, sizeof v);
      double out = 0;
      if ((i & 0x8000u) == 0 && std::isfinite(v) && v > 0) {
        const double db = 20.0 * std::log10(static_cast<double>(v));
        out = std::clamp((db + o.dynamic_range_db) / o.dynamic_range_db * 255.0, 0.0, 255.0);
      } else if ((i & 0x8000u) == 0 && std::isinf(v)) {
        out = 255;
      }
      log_lut[i] = static_cast<std::uint8_t>(std::lround(out));
    }

    // Axial pulse envelope, tabulated at kKernelPhases sub-sample phases.
    const double sigma_s = o.axial_psf_mm / dr;
    kernel_radius = std::max(1, static_cast<int>(std::ceil(3.0 * sigma_s)));
    const int taps = 2 * kernel_radius + 1;
    kernel.resize(static_cast<std::size_t>(kKernelPhases * taps));
    for (int ph = 0; ph < kKernelPhases; ++ph)
      for (int k = -kernel_radius; k <= kernel_radius; ++k) {
        const double x = (k - (ph + 0.5) / kKernelPhases) / sigma_s;
        kernel[static_cast<std::size_t>(ph * taps + k + kernel_radius)] =
            static_cast<float>(std::exp(-0.5 * x * x));
      }
    lat_az = GaussianTaps(o.lateral_psf_beams, true);
    lat_el = GaussianTaps(o.elevation_psf_beams, true);

    BuildSpeckle(o, sigma_s);
    echoes.resize(static_cast<std::size_t>(nb) * kMaxEchoes);
    echo_count.resize(static_cast<std::size_t>(nb));
    segments.resize(static_cast<std::size_t>(nb) * kMaxSegments);
    segment_count.resize(static_cast<std::size_t>(nb));
    polar.resize(probe.polar_size());
    rng.seed(o.seed);
  }

  // Rayleigh speckle: |complex white field ⊗ PSF| (separable Gaussian: axial, azimuth,
  // elevation), normalised to unit mean, on 2·n_elevation rows of beams (+ n_samples) so
  // that frames can read it at a random offset.
  void BuildSpeckle(const SimulatedScannerOptions& o, double sigma_s) {
    const std::size_t ns = static_cast<std::size_t>(probe.n_samples);
    const std::size_t na = static_cast<std::size_t>(probe.n_azimuth);
    const std::size_t ne = 2 * static_cast<std::size_t>(probe.n_elevation);
    const std::size_t n = ne * na * ns;
    // Three fields of scratch, each pass overwriting one whole (no zero fill): the white
    // field's real and imaginary parts, then each part's three passes ping-pong through the
    // third.
    std::unique_ptr<float[]> buf[3] = {std::make_unique_for_overwrite<float[]>(n),
                                       std::make_unique_for_overwrite<float[]>(n),
                                       std::make_unique_for_overwrite<float[]>(n)};
    float* re = buf[0].get();
    float* im = buf[1].get();
    float* spare = buf[2].get();
    const std::uint64_t seed = SplitMix(o.seed ^ 0x5eed5eedull);
    tbb::parallel_for(std::size_t{0}, ne * na, [&](std::size_t b) {
      for (std::size_t s = 0; s < ns; ++s) {
        const std::size_t i = b * ns + s;
        const std::uint64_t h = SplitMix(seed + i);
        re[i] = static_cast<float>(h & 0xFFFFFFFFu) * (2.0f / 4294967296.0f) - 1.0f;
        im[i] = static_cast<float>(h >> 32) * (2.0f / 4294967296.0f) - 1.0f;
      }
    });
    const std::vector<float> axial = GaussianTaps(sigma_s, false);
    const std::vector<float> azimuth = GaussianTaps(o.lateral_psf_beams, false);
    const std::vector<float> elevation = GaussianTaps(o.elevation_psf_beams, false);
    for (float** field : {&re, &im}) {
      SmoothWrapped(*field, spare, n, 1, ns, axial);
      SmoothWrapped(spare, *field, n, ns, na, azimuth);
      SmoothWrapped(*field, spare, n, ns * na, ne, elevation);
      std::swap(*field, spare);  // the smoothed part; its old buffer is free
    }
    float* magnitude = spare;
    double sum = 0;
    for (std::size_t i = 0; i < n; ++i) {
      magnitude[i] = std::sqrt(re[i] * re[i] + im[i] * im[i]);
      sum += magnitude[i];
    }
    const float scale = static_cast<float>(kSpeckleScale / (sum / static_cast<double>(n)));
    speckle.resize(n + ns);
    for (std::size_t i = 0; i < n; ++i)
      speckle[i] = static_cast<std::uint8_t>(std::min(255.0f, std::round(magnitude[i] * scale)));
    for (std::size_t i = 0; i < ns; ++i) speckle[n + i] = speckle[i];
  }

  ProbeGeometry probe;
  ScanConverter converter;
  double depth_scale;
  Eigen::Isometry3d world_to_probe;
  Eigen::Vector3f origin_world;
  std::vector<Eigen::Vector3f> beam_dirs;
  float true_range_mm;
  float samples_per_true_mm;
  Scene scene;
  int tank_id = -1, sheath_id = -1, wire_id = -1, annulus_id = -1;
  std::vector<AcousticProperties> props;
  std::vector<float> gain;
  float echo_scale;
  float noise_level;
  float background = 0.0f;
  std::vector<std::uint8_t> log_lut;
  int kernel_radius = 1;
  std::vector<float> kernel;
  std::vector<float> lat_az, lat_el;
  std::vector<std::uint8_t> speckle;
  std::vector<Echo> echoes;
  std::vector<int> echo_count;
  std::vector<Segment> segments;
  std::vector<int> segment_count;
  std::vector<std::uint8_t> polar;
  std::mt19937_64 rng;
  CatheterPose pose;

  void TraceBeam(int b) {
    RayHit hits[kMaxHits];
    const int n = scene.TraceAll(origin_world, beam_dirs[static_cast<std::size_t>(b)],
                                 true_range_mm, hits, kMaxHits);
    Echo* ec = &echoes[static_cast<std::size_t>(b) * kMaxEchoes];
    Segment* sg = &segments[static_cast<std::size_t>(b) * kMaxSegments];
    int ne = 0, nsg = 0;
    float t_amp = 1.0f, scatter = 0.0f;
    sg[nsg++] = {0.0f, background};
    for (int i = 0; i < n && t_amp > 1e-4f; ++i) {
      const RayHit& h = hits[i];
      const AcousticProperties& p = props[static_cast<std::size_t>(h.mesh)];
      const float s = h.t_mm * samples_per_true_mm;
      const float amp =
          t_amp *
          static_cast<float>(p.specular * std::pow(h.cos_incidence, p.specularity) + p.diffuse);
      if (ne < kMaxEchoes) ec[ne++] = {s, amp};
      if (p.is_metal && h.entering) {
        for (int j = i + 1; j < n; ++j) {
          if (hits[j].mesh != h.mesh) continue;
          const float d = (hits[j].t_mm - h.t_mm) * samples_per_true_mm;
          float a = amp;
          for (int k = 1; k <= p.reverb_count && ne < kMaxEchoes; ++k) {
            a *= static_cast<float>(p.reverb_decay);
            ec[ne++] = {hits[j].t_mm * samples_per_true_mm + k * d, a};
          }
          break;
        }
      }
      t_amp *= static_cast<float>(p.transmission);
      if (p.scatter > 0) scatter = h.entering ? static_cast<float>(p.scatter) : 0.0f;
      if (nsg < kMaxSegments) sg[nsg++] = {s, (background + scatter) * t_amp};
    }
    echo_count[static_cast<std::size_t>(b)] = ne;
    segment_count[static_cast<std::size_t>(b)] = nsg;
  }

  void FormBeam(int ia, int ie, const std::uint8_t* spk, const std::uint8_t* noise, float* line) {
    const int ns = probe.n_samples, na = probe.n_azimuth;
    const int b = ie * na + ia;
    const Segment* sg = &segments[static_cast<std::size_t>(b) * kMaxSegments];
    const int nsg = segment_count[static_cast<std::size_t>(b)];
    for (int i = 0; i < nsg; ++i) {
      const int s0 = std::max(0, static_cast<int>(std::ceil(sg[i].sample)));
      const int s1 = i + 1 < nsg ? std::min(ns, static_cast<int>(std::ceil(sg[i + 1].sample))) : ns;
      const float level = sg[i].level;
      for (int s = s0; s < s1; ++s) line[s] = level * spk[s];
    }
    const int ra = static_cast<int>(lat_az.size() / 2), re = static_cast<int>(lat_el.size() / 2);
    const int taps = 2 * kernel_radius + 1;
    for (int de = -re; de <= re; ++de) {
      const int je = ie + de;
      if (je < 0 || je >= probe.n_elevation) continue;
      for (int da = -ra; da <= ra; ++da) {
        const int ja = ia + da;
        if (ja < 0 || ja >= na) continue;
        const std::size_t nb = static_cast<std::size_t>(je * na + ja);
        const int cnt = echo_count[nb];
        if (cnt == 0) continue;
        const float w = lat_az[static_cast<std::size_t>(da + ra)] *
                        lat_el[static_cast<std::size_t>(de + re)] * echo_scale;
        const Echo* ec = &echoes[nb * kMaxEchoes];
        for (int k = 0; k < cnt; ++k) {
          const float x = ec[k].sample;
          if (!(x > -kernel_radius && x < ns + kernel_radius)) continue;
          const int s0 = static_cast<int>(std::floor(x));
          const int ph = std::min(kKernelPhases - 1, static_cast<int>((x - s0) * kKernelPhases));
          const float* kr = &kernel[static_cast<std::size_t>(ph * taps)];
          const float a = ec[k].amp * w;
          for (int t = -kernel_radius; t <= kernel_radius; ++t) {
            const int s = s0 + t;
            if (s >= 0 && s < ns) line[s] += a * kr[t + kernel_radius];
          }
        }
      }
    }
    std::uint8_t* out = &polar[probe.PolarIndex(ia, ie, 0)];
    const std::size_t stride = static_cast<std::size_t>(na);
    const float nl = noise_level;
    for (int s = 0; s < ns; ++s) {
      const float v =
          line[s] * gain[static_cast<std::size_t>(s)] + nl * (1.0f / kSpeckleScale) * noise[s];
      std::uint32_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      out[static_cast<std::size_t>(s) * stride] = log_lut[bits >> 16];
    }
  }
};

SimulatedScanner::SimulatedScanner(SimulatedScannerOptions options) : options_(std::move(options)) {
  options_.Validate();
  impl_ = std::make_unique<Impl>(options_);
  impl_->background = static_cast<float>(options_.background_scatter);
  impl_->pose = options_.catheter_pose;
}

SimulatedScanner::~SimulatedScanner() = default;

void SimulatedScanner::SetCatheterPose(const CatheterPose& pose) {
  RequireRigid(pose.base_to_world, "catheter_pose.base_to_world");
  RequireScannerRange(pose.advance_mm, -1000, 1000, "catheter_pose.advance_mm");
  impl_->pose = pose;
}

Eigen::Vector3d SimulatedScanner::WorldToImage(const Eigen::Vector3d& world_mm) const {
  return depth_scale() * (impl_->world_to_probe * world_mm);
}

std::span<const std::uint8_t> SimulatedScanner::last_polar() const { return impl_->polar; }

std::optional<SourceFrame> SimulatedScanner::Next() {
  if (options_.max_frames >= 0 && next_frame_ >= options_.max_frames) return std::nullopt;
  const double t = options_.start_time_s + static_cast<double>(next_frame_) / options_.rate_hz;
  SourceFrame f = Render(t);
  f.volume.set_frame_index(next_frame_++);
  return f;
}

SourceFrame SimulatedScanner::Render(double t_s) {
  Impl& m = *impl_;
  if (options_.catheter_pose_at) SetCatheterPose(options_.catheter_pose_at(t_s));
  const double disp = options_.target_displacement_mm ? options_.target_displacement_mm(t_s) : 0.0;
  if (!std::isfinite(disp))
    throw std::invalid_argument("SimulatedScanner: target_displacement_mm is not finite");
  const auto& cg = options_.catheter_geometry;
  const Eigen::Isometry3d& base = m.pose.base_to_world;
  const double adv = m.pose.advance_mm;
  m.scene.SetPose(m.sheath_id, base * Eigen::Translation3d(0, 0, adv));
  m.scene.SetPose(m.wire_id, base * Eigen::Translation3d(0, 0, adv + cg.sheath_length_mm - 1.0));
  m.scene.SetPose(m.annulus_id, options_.annulus_to_world * Eigen::Translation3d(0, 0, disp));
  m.scene.Commit();

  // Speckle offsets for this frame: whole elevation rows plus a sample shift.
  const std::size_t ns = static_cast<std::size_t>(m.probe.n_samples);
  const std::size_t row = static_cast<std::size_t>(m.probe.n_azimuth) * ns;
  const std::size_t off =
      (m.rng() % static_cast<std::uint64_t>(m.probe.n_elevation)) * row + m.rng() % ns;
  const std::size_t noise_off =
      (m.rng() % static_cast<std::uint64_t>(m.probe.n_elevation)) * row + m.rng() % ns;

  const int nb = m.probe.beam_count();
  tbb::parallel_for(tbb::blocked_range<int>(0, nb, 64), [&](const tbb::blocked_range<int>& r) {
    EnableFlushToZero();
    for (int b = r.begin(); b != r.end(); ++b) m.TraceBeam(b);
  });
  // By elevation rows: a row's polar bytes (n_samples × n_azimuth) stay in cache while its
  // beams are written with stride n_azimuth.
  tbb::parallel_for(
      tbb::blocked_range<int>(0, m.probe.n_elevation, 1), [&](const tbb::blocked_range<int>& r) {
        EnableFlushToZero();
        std::vector<float> line(ns);
        for (int ie = r.begin(); ie != r.end(); ++ie) {
          for (int ia = 0; ia < m.probe.n_azimuth; ++ia) {
            const std::size_t base_idx = static_cast<std::size_t>(ie * m.probe.n_azimuth + ia) * ns;
            m.FormBeam(ia, ie, &m.speckle[off + base_idx], &m.speckle[noise_off + base_idx],
                       line.data());
          }
        }
      });

  Volume vol = Volume::Create(m.converter.geometry());
  m.converter.Convert(m.polar, vol);
  vol.set_timestamp_s(t_s);
  vol.set_probe_to_reference(options_.probe_to_world);
  vol.set_image_to_probe(Eigen::Isometry3d::Identity());  // the image frame is the probe's

  FrameGroundTruth truth;
  const Eigen::Vector3d dir_world = base.linear().col(2);
  const Eigen::Vector3d sheath_end = base * Eigen::Vector3d(0, 0, adv + cg.sheath_length_mm);
  const Eigen::Vector3d tip =
      base * Eigen::Vector3d(0, 0, adv + cg.sheath_length_mm + cg.wire_protrusion_mm);
  truth.axis_point_mm = WorldToImage(sheath_end);
  truth.axis_direction = (m.world_to_probe.linear() * dir_world).normalized();
  truth.tip_mm = WorldToImage(tip);
  Eigen::Vector3d polar_idx;
  truth.catheter_visible = options_.catheter && m.probe.ToPolar(truth.tip_mm, &polar_idx);
  if (options_.annulus) {
    RayHit hit;
    const Eigen::Vector3d from = base * Eigen::Vector3d(0, 0, adv);
    if (m.scene.FirstHitOn(m.annulus_id, from, dir_world, 1e4, &hit)) {
      truth.target_mm = WorldToImage(from + static_cast<double>(hit.t_mm) * dir_world);
      truth.target_visible = m.probe.ToPolar(truth.target_mm, &polar_idx);
    }
  }
  return SourceFrame{std::move(vol), truth};
}

}  // namespace echoservo::imaging::sim
