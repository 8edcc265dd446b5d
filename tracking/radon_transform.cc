#include "tracking/radon_transform.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>
#include <numeric>

#include "tracking/quadratic_range.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

namespace echoservo::tracking {
namespace {

using Histogram256 = std::array<std::int64_t, 256>;

// Median of the non-zero entries of a value histogram; 0 when there are none.
double MedianNonZero(const Histogram256& h) {
  std::int64_t n = 0;
  for (int i = 1; i < 256; ++i) n += h[static_cast<std::size_t>(i)];
  std::int64_t acc = 0;
  for (int i = 1; i < 256 && n > 0; ++i) {
    acc += h[static_cast<std::size_t>(i)];
    if (2 * acc >= n) return i;
  }
  return 0.0;
}

// The q-quantile (0 < q ≤ 1) of the non-zero entries of a value histogram; 0 when none.
double QuantileNonZero(const Histogram256& h, double q) {
  std::int64_t n = 0;
  for (int i = 1; i < 256; ++i) n += h[static_cast<std::size_t>(i)];
  std::int64_t acc = 0;
  for (int i = 1; i < 256 && n > 0; ++i) {
    acc += h[static_cast<std::size_t>(i)];
    if (static_cast<double>(acc) >= q * static_cast<double>(n)) return i;
  }
  return 0.0;
}

// Adds the values of `data` to `h`. Four interleaved count tables break the store-to-load
// dependency of runs of equal values; 8-byte words of zeros (most of a water-tank volume:
// the scan sector's outside and black water) are counted at once.
void AddToHistogram(std::span<const std::uint8_t> data, Histogram256& h) {
  std::array<std::array<std::uint32_t, 256>, 4> t{};
  std::uint32_t zeros = 0;
  std::size_t i = 0;
  for (; i + 8 <= data.size(); i += 8) {
    std::uint64_t word;
    std::memcpy(&word, data.data() + i, 8);
    if (word == 0) {
      zeros += 8;
      continue;
    }
    for (std::size_t b = 0; b < 8; ++b) ++t[b & 3][data[i + b]];
  }
  for (; i < data.size(); ++i) ++t[0][data[i]];
  h[0] += zeros;
  for (std::size_t v = 0; v < 256; ++v) h[v] += std::int64_t{t[0][v]} + t[1][v] + t[2][v] + t[3][v];
}

// acc[i] = max(acc[i], in[i]) for i < n (the two ranges do not overlap).
void MaxInto(std::uint8_t* __restrict acc, const std::uint8_t* __restrict in, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) acc[i] = std::max(acc[i], in[i]);
}

// Cells [io0, io1] of row (jo, ko) of the grid `src` (dims d, x fastest) pooled by f, into
// out[io0..io1]: the element-wise maximum of the block's f × f input rows (vectorises), then
// of each run of f along x. `row` is scratch of d.x bytes. Raw pointers: a store through a
// uint8_t lvalue may alias anything, so through a vector the compiler would reload its data
// pointer for every byte.
void PoolRow(const std::uint8_t* src, const Eigen::Vector3i& d, int f, int jo, int ko, int io0,
             int io1, std::uint8_t* row, std::uint8_t* out) {
  const std::size_t sx = static_cast<std::size_t>(d.x()), sy = static_cast<std::size_t>(d.y());
  const std::size_t x0 = static_cast<std::size_t>(io0) * static_cast<std::size_t>(f);
  const std::size_t x1 =
      std::min(sx, static_cast<std::size_t>(io1 + 1) * static_cast<std::size_t>(f));
  bool first = true;
  for (int k = ko * f; k < std::min(d.z(), ko * f + f); ++k)
    for (int j = jo * f; j < std::min(d.y(), jo * f + f); ++j) {
      const std::uint8_t* in =
          src + sx * (static_cast<std::size_t>(j) + sy * static_cast<std::size_t>(k)) + x0;
      if (first) {
        std::memcpy(row + x0, in, x1 - x0);
        first = false;
      } else {
        MaxInto(row + x0, in, x1 - x0);
      }
    }
  if (f == 2) {  // the common case, as a loop that vectorises
    const int pairs = std::min(io1, static_cast<int>(sx / 2) - 1);  // cells with both voxels
    for (int io = io0; io <= pairs; ++io) out[io] = std::max(row[2 * io], row[2 * io + 1]);
    for (int io = std::max(io0, pairs + 1); io <= io1; ++io)
      out[io] = row[2 * io];  // clipped last cell
    return;
  }
  for (int io = io0; io <= io1; ++io) {
    const std::size_t i0 = static_cast<std::size_t>(io) * static_cast<std::size_t>(f);
    const std::size_t i1 = std::min(sx, i0 + static_cast<std::size_t>(f));
    std::uint8_t m = row[i0];
    for (std::size_t i = i0 + 1; i < i1; ++i) m = std::max(m, row[i]);
    out[io] = m;
  }
}

// Max-pools the grid `src` (dims d, x fastest) by f; `out_factor` is the result's factor
// relative to the volume.
PooledGrid Pool(const std::uint8_t* src, const Eigen::Vector3i& d, int f, int out_factor) {
  PooledGrid g;
  g.factor = out_factor;
  g.dims = Eigen::Vector3i((d.x() + f - 1) / f, (d.y() + f - 1) / f, (d.z() + f - 1) / f);
  const std::size_t nx = static_cast<std::size_t>(g.dims.x()),
                    ny = static_cast<std::size_t>(g.dims.y());
  g.values.assign(nx * ny * static_cast<std::size_t>(g.dims.z()), 0);
  std::vector<Histogram256> slice_hist(static_cast<std::size_t>(g.dims.z()), Histogram256{});
  tbb::parallel_for(tbb::blocked_range<int>(0, g.dims.z()), [&](const tbb::blocked_range<int>& r) {
    std::vector<std::uint8_t> row(static_cast<std::size_t>(d.x()));
    for (int ko = r.begin(); ko != r.end(); ++ko) {
      std::uint8_t* out_slice = g.values.data() + nx * ny * static_cast<std::size_t>(ko);
      for (int jo = 0; jo < g.dims.y(); ++jo)
        PoolRow(src, d, f, jo, ko, 0, g.dims.x() - 1, row.data(),
                out_slice + nx * static_cast<std::size_t>(jo));
      AddToHistogram(std::span<const std::uint8_t>(out_slice, nx * ny),
                     slice_hist[static_cast<std::size_t>(ko)]);
    }
  });
  for (const auto& h : slice_hist)
    for (std::size_t v = 0; v < 256; ++v) g.histogram[v] += h[v];
  return g;
}

// The cells of one grid slice that may lie within a region of interest. The squared distance
// of the (unclipped) cell centres to the region's line is a quadratic in (i, j):
// |c + i a + j b|² with a, b the cell steps and c cell (0, 0) of the slice, all ⟂ the line.
class SliceRows {
 public:
  SliceRows(const Eigen::Vector3d& corner, const Eigen::Vector3d& di, const Eigen::Vector3d& dj,
            const RadonWindow* roi, double radius_mm, const Eigen::Vector2i& dims)
      : dims_(dims), all_(roi == nullptr) {
    if (all_) return;
    const Eigen::Vector3d e = roi->line.direction;
    auto perp = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return x - x.dot(e) * e; };
    const Eigen::Vector3d a = perp(di), b = perp(dj), c = perp(corner - roi->line.point);
    aa_ = a.squaredNorm();
    ab_ = a.dot(b);
    ac_ = a.dot(c);
    bb_ = b.squaredNorm();
    bc_ = b.dot(c);
    cc_ = c.squaredNorm();
    r2_ = radius_mm * radius_mm;
  }

  // [j0, j1]: the rows that may hold such cells (the quadratic's minimum over i, a quadratic
  // in j, small enough).
  bool Rows(int& j0, int& j1) const {
    if (all_) {
      j0 = 0;
      j1 = dims_.y() - 1;
      return true;
    }
    if (aa_ <= 1e-12) return QuadraticRange(bb_, bc_, cc_ - r2_, dims_.y(), j0, j1);
    return QuadraticRange(bb_ - ab_ * ab_ / aa_, bc_ - ac_ * ab_ / aa_, cc_ - ac_ * ac_ / aa_ - r2_,
                          dims_.y(), j0, j1);
  }

  // [i0, i1]: the cells of row j that may be such cells.
  bool Row(int j, int& i0, int& i1) const {
    if (all_) {
      i0 = 0;
      i1 = dims_.x() - 1;
      return true;
    }
    return QuadraticRange(aa_, ac_ + j * ab_, cc_ + 2 * j * bc_ + j * j * bb_ - r2_, dims_.x(), i0,
                          i1);
  }

 private:
  Eigen::Vector2i dims_;
  bool all_;
  double aa_ = 0, ab_ = 0, ac_ = 0, bb_ = 0, bc_ = 0, cc_ = 0, r2_ = 0;
};

// The cell centres of a grid of `v` pooled by `factor`, and the part of each grid row that
// may lie within a region of interest.
class GridGeometry {
 public:
  GridGeometry(const imaging::Volume& v, int factor, const Eigen::Vector3i& dims)
      : f_(factor),
        dims_(dims),
        volume_dims_(v.dims()),
        origin_(v.origin_mm()),
        // As Volume::IndexToPhysical (the same matrix and sum), inlined.
        to_physical_(v.direction() * v.spacing_mm().asDiagonal()),
        di_(Centre(1, 0, 0) - Centre(0, 0, 0)),
        dj_(Centre(0, 1, 0) - Centre(0, 0, 0)),
        slack_mm_(0.5 * factor * v.spacing_mm().maxCoeff() + 1e-6) {}

  Eigen::Vector3d Centre(int i, int j, int k) const {
    const Eigen::Vector3i& d = volume_dims_;
    const Eigen::Vector3d idx(std::min<double>(i * f_ + 0.5 * (f_ - 1), d.x() - 1),
                              std::min<double>(j * f_ + 0.5 * (f_ - 1), d.y() - 1),
                              std::min<double>(k * f_ + 0.5 * (f_ - 1), d.z() - 1));
    return origin_ + to_physical_ * idx;
  }

  // The cells of slice k that may lie within `roi` (all of them without one). The last
  // cell of a row, and the last row, may be clipped back towards the others by up to
  // (f − 1)/2 voxels: the radius is widened by that (cells are then tested exactly).
  SliceRows Slice(int k, const RadonWindow* roi) const {
    return SliceRows(Centre(0, 0, k), di_, dj_, roi, roi ? roi->radius_mm + 2 * slack_mm_ : 0.0,
                     Eigen::Vector2i(dims_.x(), dims_.y()));
  }

 private:
  int f_;
  Eigen::Vector3i dims_, volume_dims_;
  Eigen::Vector3d origin_;
  Eigen::Matrix3d to_physical_;
  Eigen::Vector3d di_, dj_;
  double slack_mm_;
};

// The first index in [i, end) whose value exceeds `above` (end when none): the scan of
// a mostly dark row, 16 cells to a compare where SSE2 is there.
int NextAbove(const std::uint8_t* row, int i, int end, std::uint8_t above) {
#if defined(__SSE2__)
  const __m128i t = _mm_set1_epi8(static_cast<char>(above));
  for (; i + 16 <= end; i += 16) {
    const __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + i));
    // x ≤ above in every lane exactly when max(x, above) == above.
    const int dark = _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(x, t), t));
    if (dark != 0xFFFF) return i + std::countr_one(static_cast<unsigned>(dark));
  }
#endif
  while (i < end && row[i] <= above) ++i;
  return i;
}

// The cells of grid slice k above `min_value` (and within `roi`, if any), in row order,
// weighted by (value − bg)².
void SliceCells(const imaging::Volume& v, const PooledGrid& g, int k, double bg, double min_value,
                const RadonWindow* roi, std::vector<RadonCell>& out) {
  const GridGeometry geo(v, g.factor, g.dims);
  const std::size_t nx = static_cast<std::size_t>(g.dims.x()),
                    ny = static_cast<std::size_t>(g.dims.y());
  const SliceRows rows = geo.Slice(k, roi);
  int j0 = 0, j1 = 0;
  if (!rows.Rows(j0, j1)) return;
  // A value x is kept when x > min_value: for a byte, when x > ⌊min_value⌋ (none above 255).
  assert(min_value >= 0);  // ≥ the background, a voxel value
  if (!(min_value < 255)) return;
  const auto dark = static_cast<std::uint8_t>(std::floor(min_value));
  for (int j = j0; j <= j1; ++j) {
    const std::uint8_t* row =
        g.values.data() + nx * (static_cast<std::size_t>(j) + ny * static_cast<std::size_t>(k));
    int i0 = 0, i1 = 0;
    if (!rows.Row(j, i0, i1)) continue;
    for (int i = NextAbove(row, i0, i1 + 1, dark); i <= i1;
         i = NextAbove(row, i + 1, i1 + 1, dark)) {
      const double x = row[i];
      const Eigen::Vector3d p = geo.Centre(i, j, k);
      if (roi && PointToLineDistance(roi->line, p) > roi->radius_mm) continue;
      out.push_back({p, (x - bg) * (x - bg)});
    }
  }
}

// The level's cells as float columns, relative to the histogram centre in bin units: the
// projection loop vectorises over them, four cells to an SSE register. The columns interleave
// kStreams distant parts of the cell list: consecutive splats then hit different bins, so
// their read-modify-writes do not wait on each other (cells in scan order are neighbours).
struct CellColumns {
  static constexpr std::size_t kStreams = 4;
  std::vector<float> x, y, z, w;
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();  // bounding box

  explicit CellColumns(const RadonLevel& L)
      : CellColumns(L, [](const RadonCell&) { return true; }) {}

  // The cells for which keep(cell) holds.
  template <typename Keep>
  CellColumns(const RadonLevel& L, Keep keep) {
    const std::size_t n = L.cells.size(), stride = (n + kStreams - 1) / kStreams;
    x.reserve(n);
    y.reserve(n);
    z.reserve(n);
    w.reserve(n);
    const double inv = 1.0 / L.bin_mm;
    lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    hi = -lo;
    for (std::size_t i = 0; i < stride; ++i)
      for (std::size_t s = 0; s < kStreams; ++s) {
        const std::size_t c = s * stride + i;
        if (c >= n || !keep(L.cells[c])) continue;
        const Eigen::Vector3d r = (L.cells[c].p_mm - L.centre_mm) * inv;
        x.push_back(static_cast<float>(r.x()));
        y.push_back(static_cast<float>(r.y()));
        z.push_back(static_cast<float>(r.z()));
        w.push_back(static_cast<float>(L.cells[c].weight));
        lo = lo.cwiseMin(r);
        hi = hi.cwiseMax(r);
      }
  }
  std::size_t size() const { return w.size(); }
};

// Histogram scratch of the calling thread, all zero between uses (a user clears the bins it
// touched): a direction then costs its splats and the bins near them, not an allocation and
// n² bins.
std::vector<float>& Scratch(std::size_t size) {
  thread_local std::vector<float> h;
  if (h.size() < size) h.assign(size, 0.0f);
  return h;
}

struct BinBox {
  int x0, y0, x1, y1;  // inclusive
  bool Empty() const { return x0 > x1 || y0 > y1; }
};

// The plane ⟂ a direction in bin units: x = c·u + off, y = c·w + off for a cell c.
struct ProjectionPlane {
  float ux, uy, uz, wx, wy, wz, off;
};

// Four floats, 16-byte aligned: one SSE register. Uninitialised unless value-initialised
// (Quad{} is zero), so that a block's scratch costs no fill.
struct alignas(16) Quad {
  float v[4];
};

// q += w, element by element (one 16-byte read-modify-write with SSE2).
inline void AddQuad(Quad& q, const Quad& w) {
#if defined(__SSE2__)
  _mm_store_ps(q.v, _mm_add_ps(_mm_load_ps(q.v), _mm_load_ps(w.v)));
#else
  for (int k = 0; k < 4; ++k) q.v[k] += w.v[k];
#endif
}

// Lower-left bins (truncated projections) and bilinear weights {w00, w10, w01, w11} of
// cells [0, m) (columns x, y, z, w); `box` grows to hold the bins. With SSE2 four cells at
// a time, in the same float operations as the scalar loop (the same sums in the same order,
// truncation by cvttps as by a cast): identical bins and weights, and no per-cell branch.
void ProjectBlock(const ProjectionPlane& p, const float* cx, const float* cy, const float* cz,
                  const float* cw, std::size_t m, std::int32_t* bx, std::int32_t* by, Quad* wq,
                  BinBox& box) {
  // Locals: the stores through float pointers could otherwise alias `p`, forcing reloads.
  const float ux = p.ux, uy = p.uy, uz = p.uz, wx = p.wx, wy = p.wy, wz = p.wz, off = p.off;
  std::int32_t x0 = box.x0, y0 = box.y0, x1 = box.x1, y1 = box.y1;
  std::size_t i = 0;
#if defined(__SSE2__)
  if (m >= 4) {
    const __m128 vux = _mm_set1_ps(ux), vuy = _mm_set1_ps(uy), vuz = _mm_set1_ps(uz);
    const __m128 vwx = _mm_set1_ps(wx), vwy = _mm_set1_ps(wy), vwz = _mm_set1_ps(wz);
    const __m128 voff = _mm_set1_ps(off), one = _mm_set1_ps(1.0f);
    const float inf = std::numeric_limits<float>::infinity();
    __m128 min_x = _mm_set1_ps(inf), min_y = min_x, max_x = _mm_set1_ps(-inf), max_y = max_x;
    for (; i + 4 <= m; i += 4) {
      const __m128 x = _mm_loadu_ps(cx + i), y = _mm_loadu_ps(cy + i), z = _mm_loadu_ps(cz + i);
      const __m128 w = _mm_loadu_ps(cw + i);
      const __m128 px = _mm_add_ps(
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(x, vux), _mm_mul_ps(y, vuy)), _mm_mul_ps(z, vuz)), voff);
      const __m128 py = _mm_add_ps(
          _mm_add_ps(_mm_add_ps(_mm_mul_ps(x, vwx), _mm_mul_ps(y, vwy)), _mm_mul_ps(z, vwz)), voff);
      const __m128i ix = _mm_cvttps_epi32(px), iy = _mm_cvttps_epi32(py);
      // Truncation is monotonic: the bins' extremes are those of the projections.
      min_x = _mm_min_ps(min_x, px);
      max_x = _mm_max_ps(max_x, px);
      min_y = _mm_min_ps(min_y, py);
      max_y = _mm_max_ps(max_y, py);
      const __m128 fx = _mm_sub_ps(px, _mm_cvtepi32_ps(ix));
      const __m128 fy = _mm_sub_ps(py, _mm_cvtepi32_ps(iy));
      const __m128 a = _mm_mul_ps(w, _mm_sub_ps(one, fy)), c = _mm_mul_ps(w, fy);
      __m128 q0 = _mm_mul_ps(a, _mm_sub_ps(one, fx)), q1 = _mm_mul_ps(a, fx);
      __m128 q2 = _mm_mul_ps(c, _mm_sub_ps(one, fx)), q3 = _mm_mul_ps(c, fx);
      _MM_TRANSPOSE4_PS(q0, q1, q2, q3);  // rows: the quads of cells i … i + 3
      _mm_storeu_si128(reinterpret_cast<__m128i*>(bx + i), ix);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(by + i), iy);
      _mm_store_ps(wq[i].v, q0);
      _mm_store_ps(wq[i + 1].v, q1);
      _mm_store_ps(wq[i + 2].v, q2);
      _mm_store_ps(wq[i + 3].v, q3);
    }
    auto lane_min = [](__m128 v) {
      v = _mm_min_ps(v, _mm_movehl_ps(v, v));
      return _mm_cvttss_si32(_mm_min_ss(v, _mm_shuffle_ps(v, v, 1)));
    };
    auto lane_max = [](__m128 v) {
      v = _mm_max_ps(v, _mm_movehl_ps(v, v));
      return _mm_cvttss_si32(_mm_max_ss(v, _mm_shuffle_ps(v, v, 1)));
    };
    x0 = std::min(x0, lane_min(min_x));
    y0 = std::min(y0, lane_min(min_y));
    x1 = std::max(x1, lane_max(max_x));
    y1 = std::max(y1, lane_max(max_y));
  }
#endif
  for (; i < m; ++i) {
    const float px = cx[i] * ux + cy[i] * uy + cz[i] * uz + off;
    const float py = cx[i] * wx + cy[i] * wy + cz[i] * wz + off;
    const std::int32_t ix = static_cast<std::int32_t>(px), iy = static_cast<std::int32_t>(py);
    x0 = std::min(x0, ix);
    y0 = std::min(y0, iy);
    x1 = std::max(x1, ix);
    y1 = std::max(y1, iy);
    const float fx = px - static_cast<float>(ix), fy = py - static_cast<float>(iy);
    const float a = cw[i] * (1 - fy), c = cw[i] * fy;
    bx[i] = ix;
    by[i] = iy;
    wq[i].v[0] = a * (1 - fx);
    wq[i].v[1] = a * fx;
    wq[i].v[2] = c * (1 - fx);
    wq[i].v[3] = c * fx;
  }
  box = BinBox{x0, y0, x1, y1};
}

// Quad scratch of the calling thread, all zero between uses.
std::vector<Quad>& QuadScratch(std::size_t size) {
  thread_local std::vector<Quad> q;
  if (q.size() < size) q.assign(size, Quad{});
  return q;
}

// The Radon histogram of one direction: the level's weights splatted bilinearly onto the
// plane ⟂ d.
class DirectionHistogram {
 public:
  DirectionHistogram(const RadonLevel& L, const Eigen::Vector3d& d)
      : L_(L),
        n_(static_cast<int>(std::ceil(2 * L.half_extent_mm / L.bin_mm)) + 1),
        off_(0.5 * (n_ - 1)),
        H_(Scratch(static_cast<std::size_t>(n_) * n_)) {
    PlaneBasis(d, u_, w_);
  }
  ~DirectionHistogram() {
    if (touched_.Empty()) return;
    for (int y = touched_.y0; y <= touched_.y1; ++y)
      std::fill_n(&H_[static_cast<std::size_t>(y) * n_ + touched_.x0],
                  touched_.x1 - touched_.x0 + 1, 0.0f);
  }
  DirectionHistogram(const DirectionHistogram&) = delete;
  DirectionHistogram& operator=(const DirectionHistogram&) = delete;

  double at(int x, int y) const { return H_[static_cast<std::size_t>(y) * n_ + x]; }
  const float* row(int y) const { return &H_[static_cast<std::size_t>(y) * n_]; }

  // Splats the cells whose 2 × 2 footprint meets `needed` (all cells when null): the bins in
  // `needed` get the sums of a full splat. A cell's four bilinear weights go, as one 16-byte
  // read-modify-write, to a quad at its lower-left bin (QuadScratch); each bin of the
  // histogram is then the sum of the four quads that reach it. (Four scattered float
  // updates per cell cost more than that recombination.) Per block of cells the bins and
  // weights are computed first (ProjectBlock, vectorised), then added; the per-cell test is
  // skipped when the cells' bounding box projects inside the histogram and no `needed`.
  void Splat(const CellColumns& cells, const BinBox* needed) {
    // Lower-left bins of footprints inside the histogram and meeting `needed`.
    BinBox allow{0, 0, n_ - 2, n_ - 2};
    if (needed)
      allow = Intersect(allow, BinBox{needed->x0 - 1, needed->y0 - 1, needed->x1, needed->y1});
    if (allow.Empty() || cells.size() == 0) return;
    const BinBox box = ProjectedBox(cells);
    const bool check =
        needed || box.x0 < allow.x0 || box.y0 < allow.y0 || box.x1 > allow.x1 || box.y1 > allow.y1;
    const unsigned wx = static_cast<unsigned>(allow.x1 - allow.x0),
                   wy = static_cast<unsigned>(allow.y1 - allow.y0);
    const int stride = n_ + 1;  // quads: one zero row and column before the histogram's
    std::vector<Quad>& G = QuadScratch(static_cast<std::size_t>(stride) * stride);
    Quad* Q = G.data() + stride + 1;
    const ProjectionPlane plane{static_cast<float>(u_.x()), static_cast<float>(u_.y()),
                                static_cast<float>(u_.z()), static_cast<float>(w_.x()),
                                static_cast<float>(w_.y()), static_cast<float>(w_.z()),
                                static_cast<float>(off_)};
    constexpr std::size_t kBlock = 256;
    alignas(16) std::int32_t bx[kBlock], by[kBlock];
    Quad wq[kBlock];
    BinBox t{n_, n_, -1, -1};
    for (std::size_t b0 = 0; b0 < cells.size(); b0 += kBlock) {
      const std::size_t m = std::min(kBlock, cells.size() - b0);
      ProjectBlock(plane, cells.x.data() + b0, cells.y.data() + b0, cells.z.data() + b0,
                   cells.w.data() + b0, m, bx, by, wq, t);
      for (std::size_t i = 0; i < m; ++i) {
        if (check && ((static_cast<unsigned>(bx[i] - allow.x0) > wx) |
                      (static_cast<unsigned>(by[i] - allow.y0) > wy)))
          continue;
        AddQuad(Q[by[i] * stride + bx[i]], wq[i]);
      }
    }
    // The quads written lie in the cells' bin range within `allow`.
    t = Intersect(t, allow);
    if (t.Empty()) return;
    // Bin (x, y) receives v0 of quad (x, y), v1 of (x − 1, y), v2 of (x, y − 1) and v3 of
    // (x − 1, y − 1); the quads are zeroed again after.
    for (int y = t.y0; y <= t.y1 + 1; ++y) {
      float* h = &H_[static_cast<std::size_t>(y) * n_];
      const Quad* q = Q + static_cast<std::ptrdiff_t>(y) * stride;
      const Quad* qd = q - stride;
      for (int x = t.x0; x <= t.x1 + 1; ++x)
        h[x] = (q[x].v[0] + q[x - 1].v[1]) + (qd[x].v[2] + qd[x - 1].v[3]);
    }
    for (int y = t.y0; y <= t.y1; ++y)
      std::fill_n(Q + static_cast<std::ptrdiff_t>(y) * stride + t.x0, t.x1 - t.x0 + 1, Quad{});
    touched_ = BinBox{t.x0, t.y0, t.x1 + 1, t.y1 + 1};
  }

 private:
  // Lower-left bins of the cells, from the projections of their bounding box's corners (one
  // bin of margin for the rounding of the float projections).
  BinBox ProjectedBox(const CellColumns& cells) const {
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d c((corner & 1) ? cells.hi.x() : cells.lo.x(),
                              (corner & 2) ? cells.hi.y() : cells.lo.y(),
                              (corner & 4) ? cells.hi.z() : cells.lo.z());
      x0 = std::min(x0, c.dot(u_));
      x1 = std::max(x1, c.dot(u_));
      y0 = std::min(y0, c.dot(w_));
      y1 = std::max(y1, c.dot(w_));
    }
    auto lo = [&](double v) {
      return static_cast<int>(std::clamp(std::floor(v + off_) - 1, -2.0, n_ + 2.0));
    };
    auto hi = [&](double v) {
      return static_cast<int>(std::clamp(std::floor(v + off_) + 1, -2.0, n_ + 2.0));
    };
    return BinBox{lo(x0), lo(y0), hi(x1), hi(y1)};
  }

 public:
  // Bins that can hold a peak: 2 bins in from the border (the ring), within the touched
  // box (elsewhere the histogram is 0) and, with a window, near it.
  BinBox Candidates(const RadonWindow* window) const {
    BinBox b{std::max(2, touched_.x0), std::max(2, touched_.y0), std::min(n_ - 3, touched_.x1),
             std::min(n_ - 3, touched_.y1)};
    if (window) b = Intersect(b, WindowBox(*window));
    return b;
  }

  // Bins whose peak can lie within the window: a peak moves by at most half a bin in the
  // sub-bin refinement; one more bin absorbs rounding.
  BinBox WindowBox(const RadonWindow& window) const {
    const Eigen::Vector3d r = window.line.point - L_.centre_mm;
    const double cx = r.dot(u_) / L_.bin_mm + off_, cy = r.dot(w_) / L_.bin_mm + off_;
    const double reach = window.radius_mm / L_.bin_mm + 1.5;
    auto lo = [&](double c) { return static_cast<int>(std::max(-1.0, std::floor(c - reach))); };
    auto hi = [&](double c) { return static_cast<int>(std::min(n_ + 1.0, std::ceil(c + reach))); };
    return BinBox{lo(cx), lo(cy), hi(cx), hi(cy)};
  }

  static BinBox Intersect(const BinBox& a, const BinBox& b) {
    return BinBox{std::max(a.x0, b.x0), std::max(a.y0, b.y0), std::min(a.x1, b.x1),
                  std::min(a.y1, b.y1)};
  }

  // The peak at bin (x, y) when it is a local maximum (no 8-neighbour higher) with a
  // positive score: its value minus the maximum of the 16-bin ring 2 bins around it.
  bool PeakAt(int x, int y, RadonPeak& p) const {
    const double v = at(x, y);
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx)
        if ((dx || dy) && at(x + dx, y + dy) > v) return false;
    const double score = v - Ring(x, y);
    if (score <= 0) return false;
    p = RadonPeak{};
    p.score = score;
    Refine(x, y, p);
    return true;
  }

  double Ring(int x, int y) const {
    double ring = 0;
    for (int t = -2; t <= 2; ++t) ring = std::max({ring, at(x + t, y - 2), at(x + t, y + 2)});
    for (int t = -1; t <= 1; ++t) ring = std::max({ring, at(x - 2, y + t), at(x + 2, y + t)});
    return ring;
  }

  // Parabolic sub-bin peak position.
  void Refine(int x, int y, RadonPeak& p) const {
    const double v = at(x, y);
    const double dxd = at(x - 1, y) - 2 * v + at(x + 1, y),
                 dyd = at(x, y - 1) - 2 * v + at(x, y + 1);
    const double sx =
        dxd < 0 ? std::clamp(0.5 * (at(x - 1, y) - at(x + 1, y)) / dxd, -0.5, 0.5) : 0.0;
    const double sy =
        dyd < 0 ? std::clamp(0.5 * (at(x, y - 1) - at(x, y + 1)) / dyd, -0.5, 0.5) : 0.0;
    p.a_mm = (x + sx - off_) * L_.bin_mm;
    p.c_mm = (y + sy - off_) * L_.bin_mm;
  }

  // The peak's line lies within the window and not below the depth limit.
  bool Admissible(const RadonPeak& p, const RadonWindow* window) const {
    if (window) {
      const Eigen::Vector3d r = window->line.point - L_.centre_mm;
      if (std::hypot(p.a_mm - r.dot(u_), p.c_mm - r.dot(w_)) > window->radius_mm) return false;
    }
    return (L_.centre_mm + p.a_mm * u_ + p.c_mm * w_).z() <= L_.max_depth_z_mm;
  }

 private:
  const RadonLevel& L_;
  int n_;
  double off_;
  std::vector<float>& H_;
  Eigen::Vector3d u_, w_;
  BinBox touched_{0, 0, -1, -1};
};

struct LocalMaximum {
  float value;
  int x, y;
};

// The local maxima (no 8-neighbour higher, value > 0) among the bins of `box`, row by row.
// A bin is one exactly when it equals the maximum of its 3 × 3 neighbourhood, computed
// separably (3 along x, then 3 rows) in branch-free loops that vectorise; only the rare
// maxima then cost a branch. (Testing each bin's neighbours with branches costs a
// misprediction every few bins.)
class LocalMaxima {
 public:
  const std::vector<LocalMaximum>& Find(const DirectionHistogram& H, const BinBox& box) {
    const std::size_t width = static_cast<std::size_t>(box.x1 - box.x0 + 1);
    const std::size_t padded = (width + 7) / 8 * 8;
    for (auto& r : rows_) r.assign(width, 0.0f);
    flags_.assign(padded, 0);
    found_.clear();
    RowMax3(H, box.x0, box.y0 - 1, rows_[0]);
    RowMax3(H, box.x0, box.y0, rows_[1]);
    for (int y = box.y0; y <= box.y1; ++y) {
      RowMax3(H, box.x0, y + 1, rows_[2]);
      const float* v = H.row(y) + box.x0;
      const float *a = rows_[0].data(), *b = rows_[1].data(), *c = rows_[2].data();
      std::int32_t* f = flags_.data();
      for (std::size_t i = 0; i < width; ++i) {
        const float m = std::max(std::max(a[i], b[i]), c[i]);
        f[i] = (v[i] > 0.0f) & (v[i] >= m);
      }
      for (std::size_t i = 0; i < padded; i += 8) {
        if ((f[i] | f[i + 1] | f[i + 2] | f[i + 3] | f[i + 4] | f[i + 5] | f[i + 6] | f[i + 7]) ==
            0)
          continue;
        for (std::size_t j = i; j < i + 8; ++j)
          if (f[j]) found_.push_back({v[j], box.x0 + static_cast<int>(j), y});
      }
      std::swap(rows_[0], rows_[1]);
      std::swap(rows_[1], rows_[2]);
    }
    return found_;
  }

 private:
  static void RowMax3(const DirectionHistogram& H, int x0, int y, std::vector<float>& out) {
    const float* r = H.row(y) + x0 - 1;  // r[i] is bin x0 + i − 1 (the caller keeps x0 ≥ 1)
    for (std::size_t i = 0; i < out.size(); ++i)
      out[i] = std::max(std::max(r[i], r[i + 1]), r[i + 2]);
  }
  std::array<std::vector<float>, 3> rows_;
  std::vector<std::int32_t> flags_;
  std::vector<LocalMaximum> found_;
};

// The best admissible peak of direction d (score −1 when none). Only the bins the window
// can use are splatted. A score never exceeds its bin's value, so after the highest local
// maximum only those higher than the best score so far are scored.
RadonPeak BestPeak(const RadonLevel& L, const CellColumns& cells, const Eigen::Vector3d& d,
                   const RadonWindow* window) {
  DirectionHistogram H(L, d);
  BinBox needed;
  if (window) {
    const BinBox w = H.WindowBox(*window);
    needed = BinBox{w.x0 - 2, w.y0 - 2, w.x1 + 2, w.y1 + 2};
  }
  H.Splat(cells, window ? &needed : nullptr);
  RadonPeak best;
  const BinBox c = H.Candidates(window);
  if (c.Empty()) return best;
  thread_local LocalMaxima finder;
  const std::vector<LocalMaximum>& maxima = finder.Find(H, c);
  if (maxima.empty()) return best;
  const auto top = std::max_element(
      maxima.begin(), maxima.end(),
      [](const LocalMaximum& a, const LocalMaximum& b) { return a.value < b.value; });
  double best_score = 0;
  auto consider = [&](const LocalMaximum& m) {
    RadonPeak p;
    if (m.value > best_score && H.PeakAt(m.x, m.y, p) && p.score > best_score &&
        H.Admissible(p, window)) {
      best = p;
      best_score = p.score;
    }
  };
  consider(*top);
  for (const auto& m : maxima) consider(m);
  return best;
}

// The cells that can reach the bins a window search uses for any of `dirs`. A cell c at
// distance ρ from the window's line (point p0, direction d0) lies at least
// ρ − |c − p0| · sin θ from the line through p0 along a direction d at angle θ from d0
// (the projections onto the planes ⟂ d and ⟂ d0 differ by at most sin θ in norm). A peak
// inside the window lies within radius + 0.71 bins of p0's projection (the sub-bin shift),
// its value, neighbours and ring within 2√2 bins of it, and a cell's splat within √2 bins of
// the cell: cells farther than radius + 5 bins for the largest θ add nothing to the bins
// that decide the result, so dropping them leaves it unchanged.
CellColumns WindowCells(const RadonLevel& L, std::span<const Eigen::Vector3d> dirs,
                        const RadonWindow& window) {
  const Eigen::Vector3d d0 = window.line.direction.normalized();
  double cos_min = 1.0;
  for (const auto& d : dirs) cos_min = std::min(cos_min, std::abs(d.normalized().dot(d0)));
  const double sin_max = std::sqrt(std::max(0.0, 1.0 - cos_min * cos_min));
  const double reach = window.radius_mm + 5.0 * L.bin_mm;
  const Eigen::Vector3d p0 = window.line.point;
  return CellColumns(L, [&](const RadonCell& c) {
    const Eigen::Vector3d r = c.p_mm - p0;
    const double rr = r.squaredNorm(), t = r.dot(d0);
    const double bound = reach + std::sqrt(rr) * sin_max;  // distance to the window's line ≤ bound
    return rr - t * t <= bound * bound;
  });
}

// Robust z-score (median / MAD) of `top` among `all`.
double RobustZ(std::vector<double>& all, double top) {
  const MedianMad m = ComputeMedianMad(all);
  return (top - m.median) / (1.4826 * m.mad + 1e-9 * top + 1e-12);
}

}  // namespace

MedianMad ComputeMedianMad(std::vector<double>& values) {
  if (values.empty()) return {};
  const auto mid = values.begin() + static_cast<long>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  MedianMad m;
  m.median = *mid;
  for (auto& x : values) x = std::abs(x - m.median);
  std::nth_element(values.begin(), mid, values.end());
  m.mad = *mid;
  return m;
}

double MedianNonZeroVoxel(const imaging::Volume& v) {
  const auto vox = v.voxels();
  constexpr std::size_t kChunk = std::size_t{1} << 18;  // < 2^32 per count table
  const std::size_t chunks = (vox.size() + kChunk - 1) / kChunk;
  const Histogram256 h = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, chunks), Histogram256{},
      [&](const tbb::blocked_range<std::size_t>& r, Histogram256 acc) {
        for (std::size_t c = r.begin(); c != r.end(); ++c) {
          const std::size_t a = c * kChunk;
          AddToHistogram(vox.subspan(a, std::min(kChunk, vox.size() - a)), acc);
        }
        return acc;
      },
      [](Histogram256 a, const Histogram256& b) {
        for (std::size_t i = 0; i < 256; ++i) a[i] += b[i];
        return a;
      });
  return MedianNonZero(h);
}

PooledGrid MaxPool(const imaging::Volume& v, int f) {
  f = std::max(1, f);
  return Pool(v.voxels().data(), v.dims(), f, f);
}

namespace {

// Calls row(ko, jo, io0, io1, scratch) for the part [io0, io1] of each row (jo, ko) of the
// grid `geo` (with `slices` slices) that may lie within `roi`; slices in parallel (TBB), so a
// call writes only its own slice's cells. `scratch` is the calling thread's buffer.
template <typename Row>
void ForEachRegionRow(const GridGeometry& geo, int slices, const RadonWindow& roi, Row row) {
  tbb::parallel_for(tbb::blocked_range<int>(0, slices), [&](const tbb::blocked_range<int>& r) {
    thread_local std::vector<std::uint8_t> scratch;
    for (int ko = r.begin(); ko != r.end(); ++ko) {
      const SliceRows rows = geo.Slice(ko, &roi);
      int jo0 = 0, jo1 = 0;
      if (!rows.Rows(jo0, jo1)) continue;
      for (int jo = jo0; jo <= jo1; ++jo) {
        int io0 = 0, io1 = 0;
        if (rows.Row(jo, io0, io1)) row(ko, jo, io0, io1, scratch);
      }
    }
  });
}

// A grid of `in` (dims) pooled by `by`, `total` times the volume's voxels, all 0.
void ShapeGrid(PooledGrid& g, const Eigen::Vector3i& in, int by, int total) {
  g.factor = total;
  g.dims = Eigen::Vector3i((in.x() + by - 1) / by, (in.y() + by - 1) / by, (in.z() + by - 1) / by);
  g.values.assign(static_cast<std::size_t>(g.dims.x()) * g.dims.y() * g.dims.z(), 0);
}

// The start of row (j, k) of grid g.
std::uint8_t* RowOf(PooledGrid& g, int j, int k) {
  return g.values.data() + static_cast<std::size_t>(g.dims.x()) *
                               (static_cast<std::size_t>(j) +
                                static_cast<std::size_t>(g.dims.y()) * static_cast<std::size_t>(k));
}

}  // namespace

PooledGrid MaxPool(const imaging::Volume& v, int f, const RadonWindow& roi) {
  f = std::max(1, f);
  const Eigen::Vector3i d = v.dims();
  PooledGrid g;
  ShapeGrid(g, d, f, f);
  ForEachRegionRow(GridGeometry(v, f, g.dims), g.dims.z(), roi,
                   [&](int ko, int jo, int io0, int io1, std::vector<std::uint8_t>& scratch) {
                     scratch.resize(static_cast<std::size_t>(d.x()));
                     PoolRow(v.voxels().data(), d, f, jo, ko, io0, io1, scratch.data(),
                             RowOf(g, jo, ko));
                   });
  return g;
}

NestedGrids MaxPoolNested(const imaging::Volume& v, int f, int factor, const RadonWindow& roi) {
  f = std::max(1, f);
  factor = std::max(1, factor);
  NestedGrids out;
  const Eigen::Vector3i d = v.dims();
  ShapeGrid(out.fine, d, f, f);
  ShapeGrid(out.coarse, out.fine.dims, factor, f * factor);
  const Eigen::Vector3i df = out.fine.dims;
  // Per coarse row part in the region: the fine cells beneath it (from the volume), then
  // the coarse cells from those.
  ForEachRegionRow(GridGeometry(v, f * factor, out.coarse.dims), out.coarse.dims.z(), roi,
                   [&](int ko, int jo, int io0, int io1, std::vector<std::uint8_t>& scratch) {
                     scratch.resize(static_cast<std::size_t>(std::max(d.x(), df.x())));
                     const int if0 = io0 * factor,
                               if1 = std::min(df.x() - 1, (io1 + 1) * factor - 1);
                     for (int kf = ko * factor; kf < std::min(df.z(), (ko + 1) * factor); ++kf)
                       for (int jf = jo * factor; jf < std::min(df.y(), (jo + 1) * factor); ++jf)
                         PoolRow(v.voxels().data(), d, f, jf, kf, if0, if1, scratch.data(),
                                 RowOf(out.fine, jf, kf));
                     PoolRow(out.fine.values.data(), df, factor, jo, ko, io0, io1, scratch.data(),
                             RowOf(out.coarse, jo, ko));
                   });
  return out;
}

LevelThresholds GridThresholds(const PooledGrid& g, double min_contrast) {
  const double bg = MedianNonZero(g.histogram);
  // The bright end: the 99th percentile, so that a few outlier voxels do not set it.
  const double bright = std::max(bg, QuantileNonZero(g.histogram, 0.99));
  return LevelThresholds{bg, bg + min_contrast * (bright - bg)};
}

PooledGrid MaxPool(const PooledGrid& g, int f) {
  f = std::max(1, f);
  return Pool(g.values.data(), g.dims, f, g.factor * f);
}

RadonLevel MakeRadonLevel(const imaging::Volume& v, const PooledGrid& g, double max_depth_fraction,
                          const RadonWindow* roi, double min_contrast) {
  return MakeRadonLevel(v, g, max_depth_fraction, roi, GridThresholds(g, min_contrast));
}

RadonLevel MakeRadonLevel(const imaging::Volume& v, const PooledGrid& g, double max_depth_fraction,
                          const RadonWindow* roi, const LevelThresholds& thresholds) {
  RadonLevel L;
  const double bg = thresholds.background;
  L.background = bg;
  L.min_value = std::max(bg, thresholds.min_value);
  // Per-slice cell lists, concatenated in slice order: the same cells in the same order as a
  // serial scan, so the Radon sums do not depend on the thread schedule.
  std::vector<std::vector<RadonCell>> slices(static_cast<std::size_t>(g.dims.z()));
  tbb::parallel_for(0, g.dims.z(), [&](int k) {
    SliceCells(v, g, k, bg, L.min_value, roi, slices[static_cast<std::size_t>(k)]);
  });
  std::size_t total = 0;
  for (const auto& s : slices) total += s.size();
  L.cells.reserve(total);
  for (const auto& s : slices) L.cells.insert(L.cells.end(), s.begin(), s.end());
  L.bin_mm = g.factor * std::cbrt(v.spacing_mm().prod());
  const auto box = v.BoundingBoxMm();
  L.centre_mm = box.center();
  L.half_extent_mm = 0.5 * box.diagonal().norm() + 2 * L.bin_mm;
  L.max_depth_z_mm = box.min().z() + max_depth_fraction * (box.max().z() - box.min().z());
  return L;
}

RadonLevel MakeRadonLevel(const imaging::Volume& v, int f, double max_depth_fraction) {
  return MakeRadonLevel(v, MaxPool(v, f), max_depth_fraction);
}

void PlaneBasis(const Eigen::Vector3d& d, Eigen::Vector3d& u, Eigen::Vector3d& w) {
  u = d.unitOrthogonal();
  w = d.cross(u).normalized();
}

std::vector<RadonPeak> RadonPeaks(const RadonLevel& L, const Eigen::Vector3d& d,
                                  const RadonWindow* window, bool want_z) {
  DirectionHistogram H(L, d);
  H.Splat(CellColumns(L), nullptr);
  std::vector<RadonPeak> peaks;
  std::vector<double> all;
  // The z-score needs every bin's score; the peaks alone only the bins near the window, and
  // of those only the local maxima (found a row at a time, in the same order).
  const BinBox c = H.Candidates(want_z ? nullptr : window);
  if (!want_z) {
    thread_local LocalMaxima finder;
    if (!c.Empty())
      for (const LocalMaximum& m : finder.Find(H, c)) {
        RadonPeak p;
        if (H.PeakAt(m.x, m.y, p) && H.Admissible(p, window)) peaks.push_back(p);
      }
  } else {
    for (int y = c.y0; y <= c.y1; ++y)
      for (int x = c.x0; x <= c.x1; ++x) {
        if (H.at(x, y) <= 0) continue;
        all.push_back(std::max(0.0, H.at(x, y) - H.Ring(x, y)));
        RadonPeak p;
        if (H.PeakAt(x, y, p) && H.Admissible(p, window)) peaks.push_back(p);
      }
  }
  std::sort(peaks.begin(), peaks.end(),
            [](const RadonPeak& a, const RadonPeak& b) { return a.score > b.score; });
  if (want_z && !peaks.empty() && all.size() > 8)
    peaks.front().z = RobustZ(all, peaks.front().score);
  return peaks;
}

Line3 PeakLine(const RadonLevel& L, const Eigen::Vector3d& d, const RadonPeak& p) {
  Eigen::Vector3d u, w;
  PlaneBasis(d, u, w);
  return Line3{L.centre_mm + p.a_mm * u + p.c_mm * w, d.normalized()};
}

std::vector<Eigen::Vector3d> FibonacciHemisphere(int n) {
  std::vector<Eigen::Vector3d> dirs;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (i + 0.5) / n;  // hemisphere z ∈ (0, 1)
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    dirs.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return dirs;
}

std::vector<Eigen::Vector3d> DirectionCone(const Eigen::Vector3d& d, double half, int steps) {
  Eigen::Vector3d u, w;
  PlaneBasis(d, u, w);
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < steps; ++j) {
      const double a = steps > 1 ? -half + 2 * half * i / (steps - 1) : 0.0;
      const double b = steps > 1 ? -half + 2 * half * j / (steps - 1) : 0.0;
      dirs.push_back((d + std::tan(a) * u + std::tan(b) * w).normalized());
    }
  return dirs;
}

namespace {

// SearchDirections over `cells` (the level's, or a window's superset of WindowCells').
RadonSearchResult SearchIn(const RadonLevel& L, const CellColumns& cells,
                           std::span<const Eigen::Vector3d> dirs, const RadonWindow* window) {
  std::vector<RadonPeak> best(dirs.size());
  tbb::parallel_for(std::size_t{0}, dirs.size(),
                    [&](std::size_t i) { best[i] = BestPeak(L, cells, dirs[i], window); });
  RadonSearchResult b;
  b.scores.reserve(dirs.size());
  b.directions.assign(dirs.begin(), dirs.end());
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    b.scores.push_back(std::max(0.0, best[i].score));
    if (best[i].score > b.peak.score) {
      b.peak = best[i];
      b.direction = dirs[i];
    }
  }
  b.peaks = std::move(best);
  return b;
}

// The cells a search over any of `dirs` within `window` (all, without one) can use.
CellColumns SearchCells(const RadonLevel& L, std::span<const Eigen::Vector3d> dirs,
                        const RadonWindow* window) {
  return window ? WindowCells(L, dirs, *window) : CellColumns(L);
}

}  // namespace

RadonSearchResult SearchDirections(const RadonLevel& L, std::span<const Eigen::Vector3d> dirs,
                                   const RadonWindow* window) {
  return SearchIn(L, SearchCells(L, dirs, window), dirs, window);
}

namespace {

// The indices of the top_k best of `scores`, best first (equal scores: the earlier first).
std::vector<std::size_t> BestIndices(const std::vector<double>& scores, int top_k) {
  std::vector<std::size_t> order(scores.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  const std::size_t k = std::min(order.size(), static_cast<std::size_t>(std::max(0, top_k)));
  std::partial_sort(order.begin(), order.begin() + static_cast<long>(k), order.end(),
                    [&](std::size_t a, std::size_t c) {
                      return scores[a] > scores[c] || (scores[a] == scores[c] && a < c);
                    });
  order.resize(k);
  return order;
}

// A two-stage search's result: the first stage's `b`, its peak replaced by the second
// stage's (`second`) when that scores higher.
RadonSearchResult WithSecondStage(const RadonLevel& L, const CellColumns& cells,
                                  const std::vector<Eigen::Vector3d>& second,
                                  const RadonWindow* window, RadonSearchResult b) {
  if (second.empty()) return b;
  const RadonSearchResult r = SearchIn(L, cells, second, window);
  if (r.peak.score > b.peak.score) {
    b.peak = r.peak;
    b.direction = r.direction;
  }
  return b;
}

}  // namespace

RadonSearchResult SearchDirectionsCoarseToFine(const RadonLevel& L,
                                               std::span<const Eigen::Vector3d> dirs,
                                               const CoarseToFineOptions& o,
                                               const RadonWindow* window) {
  const std::size_t stride = static_cast<std::size_t>(std::max(1, o.stride));
  // Stage 1: every stride-th direction.
  std::vector<Eigen::Vector3d> first;
  for (std::size_t i = 0; i < dirs.size(); i += stride) first.push_back(dirs[i]);
  // The cells of both stages, selected once.
  const CellColumns cells = SearchCells(L, dirs, window);
  RadonSearchResult b = SearchIn(L, cells, first, window);
  // Stage 2: the other directions near the top_k of stage 1.
  const std::vector<std::size_t> best = BestIndices(b.scores, o.top_k);
  const double cos_near = std::cos(o.neighbour_rad);
  std::vector<Eigen::Vector3d> second;
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    if (i % stride == 0) continue;
    for (const std::size_t t : best)
      if (std::abs(dirs[i].dot(first[t])) >= cos_near) {
        second.push_back(dirs[i]);
        break;
      }
  }
  return WithSecondStage(L, cells, second, window, std::move(b));
}

RadonSearchResult SearchConeCoarseToFine(const RadonLevel& L, const Eigen::Vector3d& d,
                                         double half_rad, int steps, int top_k,
                                         const RadonWindow* window) {
  const std::vector<Eigen::Vector3d> dirs = DirectionCone(d, half_rad, steps);
  auto on_subgrid = [steps](int i) { return i % 2 == 0 || i == steps - 1; };
  std::vector<int> first_ij;
  std::vector<Eigen::Vector3d> first;
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < steps; ++j)
      if (on_subgrid(i) && on_subgrid(j)) {
        first_ij.push_back(i * steps + j);
        first.push_back(dirs[static_cast<std::size_t>(i * steps + j)]);
      }
  // The cells of both stages, selected once (the sub-grid holds the grid's corners, so the
  // same cells as for it alone).
  const CellColumns cells = SearchCells(L, dirs, window);
  RadonSearchResult b = SearchIn(L, cells, first, window);
  std::vector<char> take(dirs.size(), 0);
  for (const std::size_t t : BestIndices(b.scores, top_k)) {
    if (b.scores[t] <= 0) break;
    const int i0 = first_ij[t] / steps, j0 = first_ij[t] % steps;
    for (int i = std::max(0, i0 - 1); i <= std::min(steps - 1, i0 + 1); ++i)
      for (int j = std::max(0, j0 - 1); j <= std::min(steps - 1, j0 + 1); ++j)
        if (!(on_subgrid(i) && on_subgrid(j))) take[static_cast<std::size_t>(i * steps + j)] = 1;
  }
  std::vector<Eigen::Vector3d> second;
  for (std::size_t i = 0; i < dirs.size(); ++i)
    if (take[i]) second.push_back(dirs[i]);
  return WithSecondStage(L, cells, second, window, std::move(b));
}

}  // namespace echoservo::tracking
