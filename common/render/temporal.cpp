// Object-space temporal coherence: the mark grid, the per-tile recorder and the tracker.
#include "common/render/temporal.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "common/base/error.h"

namespace rtc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Pieces per cell a marked group moves: finer pieces hug the rays closer (fewer voxels beside
/// them marked, fewer tiles retraced) for more boxes to mark.
constexpr double kPiecesPerCell = 1;

/// How much (in cells) the union of two groups may be wider than the wider of them for the two
/// to be marked as one (MarkRecorder::add_tube, add_sweep).
constexpr double kMergeCells = 0.25;

/// Widest (in cells, per axis) a group of shadow rays' surface points may be to be swept as one.
constexpr double kClusterCells = 1.0;

struct DBox {
  glm::dvec3 lo{kInf};
  glm::dvec3 hi{-kInf};
  void extend(const glm::dvec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  void extend(const DBox& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  [[nodiscard]] bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
};

/// Object-space bounds of the vertices a mesh's triangles use.
DBox object_bounds(const Mesh& mesh) {
  DBox box;
  for (const glm::uvec3& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t i = t[k];
      if (i < mesh.positions.size()) box.extend(glm::dvec3(mesh.positions[i]));
    }
  }
  return box;
}

/// Largest distance of a used vertex from the object's origin.
double object_radius(const Mesh& mesh) {
  double r2 = 0.0;
  for (const glm::uvec3& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t i = t[k];
      if (i < mesh.positions.size()) r2 = std::max(r2, glm::dot(glm::dvec3(mesh.positions[i]), glm::dvec3(mesh.positions[i])));
    }
  }
  return std::sqrt(r2);
}

/// The largest factor by which `world`'s 3x3 part stretches a vector, for rotation times
/// scale: its longest column (the rotation keeps the scaled axes orthogonal), times a hair for
/// the float matrix's rounding.
double stretch(const glm::mat4& world) {
  double best = 0.0;
  for (int c = 0; c < 3; ++c) best = std::max(best, glm::length(glm::dvec3(glm::vec3(world[c]))));
  return best * (1.0 + 1e-6);
}

/// The box of an object-space box's 8 corners under `world` (as the renderer's flatten: the
/// float matrix widened to double).
DBox transformed(const glm::dvec3& lo, const glm::dvec3& hi, const glm::mat4& world) {
  const glm::dmat4 m(world);
  DBox box;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
    box.extend(glm::dvec3(m * glm::dvec4(p, 1.0)));
  }
  return box;
}

/// Padding that covers float rounding of transformed vertices and of the triangle test, for
/// coordinates as large as those of `box`, and at least a thousandth of a cell.
double pad_for(const DBox& box, double cell) {
  const glm::dvec3 mag = glm::max(glm::abs(box.lo), glm::abs(box.hi));
  return 1e-5 * std::max({mag.x, mag.y, mag.z}) + 1e-3 * cell;
}

bool differs(const Transform& a, const Transform& b) { return !(a == b); }

}  // namespace

const char* temporal_mode_name(TemporalMode mode) {
  switch (mode) {
    case TemporalMode::On:
      return "on";
    case TemporalMode::Off:
      return "off";
    default:
      return "auto";
  }
}

TemporalMode parse_temporal_mode(const std::string& text) {
  if (text == "auto") return TemporalMode::Auto;
  if (text == "on") return TemporalMode::On;
  if (text == "off") return TemporalMode::Off;
  throw Error("temporal coherence mode must be auto, on or off, got \"" + text + "\"");
}

namespace {

bool camera_moves(const Scene& scene, int first_frame, int last_frame) {
  const std::vector<CameraKey>& keys = scene.animation.camera;
  if (keys.size() < 2) return false;
  // Between two points where it is the same the camera holds still (it interpolates linearly);
  // a pose that differs by rounding only makes the tracker trace that frame whole.
  const int first = std::max(first_frame, keys.front().frame);
  const int last = std::min(last_frame, keys.back().frame);
  if (first >= last) return false;  // the frames lie before the first key or after the last
  const Camera at_first = camera_at(scene, first);
  if (!(camera_at(scene, last) == at_first)) return true;
  for (const CameraKey& k : keys) {
    if (k.frame > first && k.frame < last && !(k.camera == at_first)) return true;
  }
  return false;
}

/// Whether frames [first_frame, last_frame] see keys a and b (strictly increasing) change what
/// they key: two or more of them lie between the keys, and the keys differ. A frame before the
/// first key or after the last holds that key.
template <class Key, class Differ>
bool seen_between(const Key& a, const Key& b, int first_frame, int last_frame, Differ differ) {
  return std::max(a.frame, first_frame) < std::min(b.frame, last_frame) && differ(a, b);
}

template <class Key, class Differ>
bool moves_between_keys(const std::vector<Key>& keys, int first_frame, int last_frame, Differ differ) {
  for (std::size_t i = 0; i + 1 < keys.size(); ++i) {
    if (seen_between(keys[i], keys[i + 1], first_frame, last_frame, differ)) return true;
  }
  return false;
}

bool transforms_differ(const TransformKey& a, const TransformKey& b) { return differs(a.transform, b.transform); }

}  // namespace

bool anything_moves(const Scene& scene, int first_frame, int last_frame) {
  if (camera_moves(scene, first_frame, last_frame)) return true;
  for (const MeshTrack& t : scene.animation.meshes) {
    if (moves_between_keys(t.keys, first_frame, last_frame, transforms_differ)) return true;
  }
  for (const LightTrack& t : scene.animation.lights) {
    if (moves_between_keys(t.keys, first_frame, last_frame,
                           [](const LightKey& a, const LightKey& b) { return !(a.position == b.position); })) {
      return true;
    }
  }
  return false;
}

bool temporal_for(const Scene& scene, TemporalMode mode, int first_frame, int last_frame, bool loop) {
  if (mode != TemporalMode::Auto) return mode == TemporalMode::On;
  if (camera_moves(scene, first_frame, last_frame)) return false;
  return !loop || anything_moves(scene, first_frame, last_frame);
}

TemporalChoice choose_temporal(const Scene& scene, TemporalMode mode, int first_frame, int last_frame, bool loop) {
  TemporalChoice c;
  c.moves = anything_moves(scene, first_frame, last_frame);
  if (mode == TemporalMode::Off) {
    c.why_off = "--temporal off";
  } else if (last_frame <= first_frame && !loop) {
    c.why_off = "one frame";
  } else if (temporal_for(scene, mode, first_frame, last_frame, loop)) {
    c.on = true;
  } else if (camera_moves(scene, first_frame, last_frame)) {
    c.why_off = "the camera moves over the frames rendered";
  } else {
    c.why_off = "--loop over frames where nothing moves: each is traced whole, as a frame-rate run needs";
  }
  return c;
}

void check_mark_grid(const MarkGrid& grid, const std::string& what) {
  if (grid.dims == glm::ivec3(0)) return;  // empty
  for (int k = 0; k < 3; ++k) {
    if (grid.dims[k] < 1 || grid.dims[k] > kMaxMarkCellsPerAxis) {
      throw Error(what + ": mark grid has " + std::to_string(grid.dims[k]) + " cells on axis " + std::to_string(k) +
                  " (1 to " + std::to_string(kMaxMarkCellsPerAxis) + " allowed)");
    }
    if (!std::isfinite(grid.lo[k]) || !std::isfinite(grid.hi[k]) || !(grid.lo[k] < grid.hi[k])) {
      throw Error(what + ": mark grid bounds on axis " + std::to_string(k) + " are not a finite interval");
    }
  }
  if (grid.voxel_count() > kMaxMarkVoxels) {
    throw Error(what + ": mark grid has " + std::to_string(grid.voxel_count()) + " voxels (at most " +
                std::to_string(kMaxMarkVoxels) + ")");
  }
}

MarkGrid mark_grid_for(const Scene& scene, int cells, int first_frame, int last_frame) {
  cells = std::clamp(cells, 1, kMaxMarkCellsPerAxis);
  // Only the key pairs whose motion the frames see count; between them the poses stay inside
  // the pair's span.
  DBox region;
  for (const MeshTrack& track : scene.animation.meshes) {
    if (track.mesh >= scene.meshes.size() || track.keys.size() < 2) continue;
    if (!moves_between_keys(track.keys, first_frame, last_frame, transforms_differ)) continue;
    const DBox obj = object_bounds(scene.meshes[track.mesh]);
    if (obj.empty()) continue;
    const double rho = object_radius(scene.meshes[track.mesh]);
    for (std::size_t i = 0; i + 1 < track.keys.size(); ++i) {
      const TransformKey& a = track.keys[i];
      const TransformKey& b = track.keys[i + 1];
      // Still, or outside the frames: its poses are another pair's ends.
      if (!seen_between(a, b, first_frame, last_frame, transforms_differ)) continue;
      const glm::mat4 ma = a.transform.matrix(), mb = b.transform.matrix();
      DBox span = transformed(obj.lo, obj.hi, ma);
      span.extend(transformed(obj.lo, obj.hi, mb));
      if (!(a.transform.rotate == b.transform.rotate)) {
        // Rotating between the keys: every vertex stays within rho times the largest scale of
        // the object's origin, which moves on the segment between the keys' translations
        // (scale is interpolated linearly, so its largest value is at a key).
        const double r = rho * std::max(stretch(ma), stretch(mb));
        const glm::dvec3 ta(ma[3]), tb(mb[3]);
        span.extend(glm::min(ta, tb) - glm::dvec3(r));
        span.extend(glm::max(ta, tb) + glm::dvec3(r));
      }
      // Translation and scale are linear between keys, so with the same rotation every vertex
      // moves on a segment between its two key positions: inside the union of the key boxes.
      region.extend(span);
    }
  }
  MarkGrid grid;
  if (region.empty()) return grid;
  const glm::dvec3 extent = region.hi - region.lo;
  const double longest = std::max({extent.x, extent.y, extent.z});
  const double pad = pad_for(region, longest / cells) + 1e-9;
  grid.lo = region.lo - glm::dvec3(pad);
  grid.hi = region.hi + glm::dvec3(pad);
  const glm::dvec3 size = grid.hi - grid.lo;
  // Fewer cells along the longest axis while the grid would hold too many voxels (a cubic
  // region passes kMaxMarkVoxels above 128 cells a side).
  for (;;) {
    const double cell = std::max({size.x, size.y, size.z}) / cells;
    for (int k = 0; k < 3; ++k) grid.dims[k] = std::clamp(static_cast<int>(std::ceil(size[k] / cell - 1e-9)), 1, cells);
    if (grid.voxel_count() <= kMaxMarkVoxels || cells == 1) return grid;
    --cells;
  }
}

// ---- recorder -------------------------------------------------------------------------------

MarkRecorder::MarkRecorder(const MarkGrid& grid) : grid_(grid) {
  if (grid_.empty()) return;
  cell_ = (grid_.hi - grid_.lo) / glm::dvec3(grid_.dims);
  inv_cell_ = 1.0 / cell_;
  DBox box;
  box.extend(grid_.lo);
  box.extend(grid_.hi);
  pad_ = pad_for(box, std::min({cell_.x, cell_.y, cell_.z}));
  const std::size_t words = (grid_.voxel_count() + 63) / 64;
  bits_[0].assign(words, 0);
  bits_[1].assign(words, 0);
}

void MarkRecorder::mark_box(int list, const glm::dvec3& lo, const glm::dvec3& hi) {
  int a[3], b[3];
  for (int k = 0; k < 3; ++k) {
    const double fa = std::floor((lo[k] - pad_ - grid_.lo[k]) * inv_cell_[k]);
    const double fb = std::floor((hi[k] + pad_ - grid_.lo[k]) * inv_cell_[k]);
    if (fb < 0.0 || fa >= grid_.dims[k]) return;
    a[k] = static_cast<int>(std::max(fa, 0.0));
    b[k] = static_cast<int>(std::min(fb, static_cast<double>(grid_.dims[k] - 1)));
  }
  // Consecutive pieces of a group often cover the same voxels: set them once.
  int* prev = last_box_[list];
  if (a[0] == prev[0] && a[1] == prev[1] && a[2] == prev[2] && b[0] == prev[3] && b[1] == prev[4] && b[2] == prev[5]) {
    return;
  }
  prev[0] = a[0], prev[1] = a[1], prev[2] = a[2], prev[3] = b[0], prev[4] = b[1], prev[5] = b[2];
  std::vector<std::uint64_t>& bits = bits_[list];
  std::vector<std::uint32_t>& touched = touched_[list];
  const auto nx = static_cast<std::uint32_t>(grid_.dims.x), ny = static_cast<std::uint32_t>(grid_.dims.y);
  for (int z = a[2]; z <= b[2]; ++z) {
    for (int y = a[1]; y <= b[1]; ++y) {
      // Voxels row+a[0] .. row+b[0] are consecutive bits: set them a word at a time.
      const std::uint32_t row = nx * (static_cast<std::uint32_t>(y) + ny * static_cast<std::uint32_t>(z));
      std::uint32_t v = row + static_cast<std::uint32_t>(a[0]);
      const std::uint32_t last = row + static_cast<std::uint32_t>(b[0]);
      while (v <= last) {
        const std::uint32_t w = v >> 6, first = v & 63;
        const std::uint32_t end = std::min<std::uint32_t>(63, first + (last - v));
        const std::uint64_t mask = (end == 63 ? ~std::uint64_t{0} : ((std::uint64_t{1} << (end + 1)) - 1)) &
                                   ~((std::uint64_t{1} << first) - 1);
        std::uint64_t& word = bits[w];
        if (word == 0) touched.push_back(w);
        word |= mask;
        v += end - first + 1;
      }
    }
  }
}

bool MarkRecorder::meets_grid(const glm::dvec3& lo_at_0, const glm::dvec3& lo_slope, const glm::dvec3& hi_at_0,
                              const glm::dvec3& hi_slope, double& t0, double& t1) const {
  for (int k = 0; k < 3 && t0 <= t1; ++k) {
    // lo(t) <= grid.hi and hi(t) >= grid.lo (the box padded), each a half-line in t.
    const double lo_a = lo_at_0[k] - pad_, lo_d = lo_slope[k];
    const double hi_a = hi_at_0[k] + pad_, hi_d = hi_slope[k];
    if (lo_d == 0.0) {
      if (lo_a > grid_.hi[k]) return false;
    } else if (lo_d > 0.0) {
      t1 = std::min(t1, (grid_.hi[k] - lo_a) / lo_d);
    } else {
      t0 = std::max(t0, (grid_.hi[k] - lo_a) / lo_d);
    }
    if (hi_d == 0.0) {
      if (hi_a < grid_.lo[k]) return false;
    } else if (hi_d > 0.0) {
      t0 = std::max(t0, (grid_.lo[k] - hi_a) / hi_d);
    } else {
      t1 = std::min(t1, (grid_.lo[k] - hi_a) / hi_d);
    }
  }
  return t0 <= t1;
}

bool MarkRecorder::path_box(const glm::vec3& o_lo, const glm::vec3& o_hi, const glm::vec3& d_lo, const glm::vec3& d_hi,
                            float t_max) {
  if (grid_.empty() || !(o_lo.x <= o_hi.x)) return true;  // nothing to mark, or no ray
  // At a common t every ray is in box(org) + t box(dir), a small box for a coherent packet
  // however its rays' lengths differ. The tube's bounds are linear in t (t >= 0), so the part of
  // [0, longest t_end] where it meets the grid takes six divisions, not six per ray.
  const glm::dvec3 olo(o_lo), ohi(o_hi), dlo(d_lo), dhi(d_hi);
  // A hit exactly where a moving mesh now starts must still count: reach a little past it.
  const double t_far = std::isfinite(t_max) ? static_cast<double>(t_max) * (1.0 + 1e-6) + 1e-30 : kInf;
  double t_lo = 0.0, t_hi = t_far;
  if (!meets_grid(olo, dlo, ohi, dhi, t_lo, t_hi)) return true;  // passes beside it
  if (!std::isfinite(t_hi)) return false;
  // Widen a hair for the rounding of the divisions above.
  t_lo = std::max(0.0, t_lo - 1e-9 * (1.0 + t_lo));
  t_hi = std::min(t_far, t_hi + 1e-9 * (1.0 + t_hi));
  add_tube(olo, ohi, dlo, dhi, t_lo, t_hi);
  return true;
}

void MarkRecorder::path_group(int n, const glm::vec3* org, const glm::vec3* dir, const float* t_end) {
  if (grid_.empty()) return;
  {
    // Boxes of floats are exact in float: min and max round nothing.
    glm::vec3 o_lo(kInfF), o_hi(-kInfF), d_lo(kInfF), d_hi(-kInfF);
    float t_max = 0.0f;
    for (int i = 0; i < n; ++i) {
      const glm::vec3& o = org[i];
      const glm::vec3& d = dir[i];
      if (!finite(o) || !finite(d) || std::isnan(t_end[i])) continue;  // hits nothing, ever
      if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) continue;
      o_lo = glm::min(o_lo, o);
      o_hi = glm::max(o_hi, o);
      d_lo = glm::min(d_lo, d);
      d_hi = glm::max(d_hi, d);
      t_max = std::max(t_max, t_end[i]);
    }
    if (path_box(o_lo, o_hi, d_lo, d_hi, t_max)) return;
    // A tube that widens in every axis (rays in several octants, unbounded) never leaves the
    // grid as a box: clip the rays one by one instead.
  }
  DBox o_box, d_box;
  double t_lo = kInf, t_hi = -kInf;
  for (int i = 0; i < n; ++i) {
    const glm::dvec3 o(org[i]), d(dir[i]);
    if (!std::isfinite(o.x + o.y + o.z + d.x + d.y + d.z) || std::isnan(t_end[i])) continue;  // hits nothing, ever
    double t0 = 0.0;
    // A hit exactly where a moving mesh now starts must still count: reach a little past it.
    double t1 = std::isfinite(t_end[i]) ? static_cast<double>(t_end[i]) * (1.0 + 1e-6) + 1e-30 : kInf;
    bool inside = true;
    for (int k = 0; k < 3 && inside; ++k) {
      if (d[k] == 0.0) {
        inside = o[k] >= grid_.lo[k] && o[k] <= grid_.hi[k];
        continue;
      }
      double ta = (grid_.lo[k] - o[k]) / d[k], tb = (grid_.hi[k] - o[k]) / d[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      inside = t0 <= t1;
    }
    if (!inside) continue;  // misses the region where anything can move
    o_box.extend(o);
    d_box.extend(d);
    t_lo = std::min(t_lo, t0);
    t_hi = std::max(t_hi, t1);
  }
  if (o_box.empty()) return;
  add_tube(o_box.lo, o_box.hi, d_box.lo, d_box.hi, t_lo, t_hi);
}

namespace {

/// Whether the union of two boxes is at most `slack` (per axis) wider than the wider of them.
bool unites(const glm::dvec3& a_lo, const glm::dvec3& a_hi, const glm::dvec3& b_lo, const glm::dvec3& b_hi,
            const glm::dvec3& slack) {
  for (int k = 0; k < 3; ++k) {
    const double merged = std::max(a_hi[k], b_hi[k]) - std::min(a_lo[k], b_lo[k]);
    if (merged > std::max(a_hi[k] - a_lo[k], b_hi[k] - b_lo[k]) + slack[k]) return false;
  }
  return true;
}

}  // namespace

void MarkRecorder::add_tube(const glm::dvec3& o_lo, const glm::dvec3& o_hi, const glm::dvec3& d_lo,
                            const glm::dvec3& d_hi, double t_lo, double t_hi) {
  // Neighbouring packets' tubes run side by side through the same voxels: the union of two
  // whose boxes at every t differ by less than kMergeCells of a cell, and whose ends are as
  // close, is marked once (a tube holds every ray of both, so the marks stay conservative).
  Tube& p = tube_;
  if (p.live) {
    double rate = 0.0;
    for (int k = 0; k < 3; ++k) {
      rate = std::max(rate, std::max({std::abs(d_lo[k]), std::abs(d_hi[k]), std::abs(p.d_lo[k]), std::abs(p.d_hi[k])}) *
                                inv_cell_[k]);
    }
    const double t_end = std::max(t_hi, p.t_hi);
    // Boxes at the far end (the widest): origin box plus t_end times the direction box.
    if (std::abs(t_hi - p.t_hi) * rate <= kMergeCells && std::abs(t_lo - p.t_lo) * rate <= kMergeCells &&
        unites(o_lo + d_lo * t_end, o_hi + d_hi * t_end, p.o_lo + p.d_lo * t_end, p.o_hi + p.d_hi * t_end,
               cell_ * kMergeCells) &&
        unites(o_lo, o_hi, p.o_lo, p.o_hi, cell_ * kMergeCells)) {
      p.o_lo = glm::min(p.o_lo, o_lo);
      p.o_hi = glm::max(p.o_hi, o_hi);
      p.d_lo = glm::min(p.d_lo, d_lo);
      p.d_hi = glm::max(p.d_hi, d_hi);
      p.t_lo = std::min(p.t_lo, t_lo);
      p.t_hi = t_end;
      return;
    }
    mark_tube(p.o_lo, p.o_hi, p.d_lo, p.d_hi, p.t_lo, p.t_hi);
  }
  p = Tube{true, o_lo, o_hi, d_lo, d_hi, t_lo, t_hi};
}

void MarkRecorder::add_sweep(const glm::dvec3& a_lo, const glm::dvec3& a_hi, const glm::dvec3& b_lo,
                             const glm::dvec3& b_hi) {
  // The same for shadow sweeps towards one light (the far ends nearly one point): a few kept
  // open at once, one per light in turn.
  for (Sweep& w : sweeps_) {
    // The light ends first: sweeps to another light fail there at once.
    if (w.live && unites(b_lo, b_hi, w.b_lo, w.b_hi, cell_ * kMergeCells) &&
        unites(a_lo, a_hi, w.a_lo, w.a_hi, cell_ * kMergeCells)) {
      w.a_lo = glm::min(w.a_lo, a_lo);
      w.a_hi = glm::max(w.a_hi, a_hi);
      w.b_lo = glm::min(w.b_lo, b_lo);
      w.b_hi = glm::max(w.b_hi, b_hi);
      return;
    }
  }
  Sweep& w = sweeps_[next_sweep_];
  next_sweep_ = (next_sweep_ + 1) % static_cast<int>(std::size(sweeps_));
  if (w.live) mark_sweep(w.a_lo, w.a_hi, w.b_lo, w.b_hi);
  w = Sweep{true, a_lo, a_hi, b_lo, b_hi};
}

void MarkRecorder::flush() {
  if (tube_.live) mark_tube(tube_.o_lo, tube_.o_hi, tube_.d_lo, tube_.d_hi, tube_.t_lo, tube_.t_hi);
  tube_.live = false;
  for (Sweep& w : sweeps_) {
    if (w.live) mark_sweep(w.a_lo, w.a_hi, w.b_lo, w.b_hi);
    w.live = false;
  }
}

void MarkRecorder::mark_tube(const glm::dvec3& o_lo, const glm::dvec3& o_hi, const glm::dvec3& d_lo,
                             const glm::dvec3& d_hi, double t_lo, double t_hi) {
  struct {
    glm::dvec3 lo, hi;
  } o_box{o_lo, o_hi}, d_box{d_lo, d_hi};
  // Pieces in t that each move about a cell.
  double rate = 0.0;
  for (int k = 0; k < 3; ++k) rate = std::max(rate, std::max(std::abs(d_box.lo[k]), std::abs(d_box.hi[k])) * inv_cell_[k]);
  const int pieces = static_cast<int>(std::clamp(std::ceil((t_hi - t_lo) * rate * kPiecesPerCell), 1.0, 16.0 * kMaxMarkCellsPerAxis));
  double ta = t_lo;
  for (int j = 1; j <= pieces; ++j) {
    const double tb = j == pieces ? t_hi : t_lo + (t_hi - t_lo) * j / pieces;
    // t d over t in [ta, tb] and d in [lo, hi] (t >= 0): extremes at the ends.
    const glm::dvec3 lo = o_box.lo + glm::min(d_box.lo * ta, d_box.lo * tb);
    const glm::dvec3 hi = o_box.hi + glm::max(d_box.hi * ta, d_box.hi * tb);
    mark_box(0, lo, hi);
    ta = tb;
  }
}

bool MarkRecorder::shadow_box(const glm::vec3& a_lo, const glm::vec3& a_hi, const glm::vec3& b_lo,
                              const glm::vec3& b_hi) {
  if (grid_.empty()) return true;
  // Infinities and NaNs fail these (NaN compares false; inf - inf is NaN, inf > limit).
  if (!(one_group(a_lo, a_hi, b_lo, b_hi) && finite(a_lo) && finite(a_hi) && finite(b_lo) && finite(b_hi))) {
    return false;
  }
  add_float_sweep(a_lo, a_hi, b_lo, b_hi);
  return true;
}

bool MarkRecorder::one_group(const glm::vec3& a_lo, const glm::vec3& a_hi, const glm::vec3& b_lo,
                             const glm::vec3& b_hi) const {
  const glm::vec3 limit = glm::vec3(cell_ * kClusterCells);
  return glm::all(glm::lessThanEqual(a_hi - a_lo, limit)) && glm::all(glm::lessThanEqual(b_hi - b_lo, limit));
}

void MarkRecorder::add_float_sweep(const glm::vec3& a_lo, const glm::vec3& a_hi, const glm::vec3& b_lo,
                                   const glm::vec3& b_hi) {
  // box(A) is exact; each B_i is within 2 ulps of max(|A_i|, |B_i|): widened in double by 1e-6
  // of the largest magnitude, far past that rounding.
  const glm::vec3 mag = glm::max(glm::max(glm::abs(a_lo), glm::abs(a_hi)), glm::max(glm::abs(b_lo), glm::abs(b_hi)));
  const double pad = 1e-6 * static_cast<double>(std::max({mag.x, mag.y, mag.z}));
  add_sweep(glm::dvec3(a_lo), glm::dvec3(a_hi), glm::dvec3(b_lo) - pad, glm::dvec3(b_hi) + pad);
}

void MarkRecorder::shadow_group(int n, const glm::vec3* org, const glm::vec3* dir, const float* t_end) {
  if (grid_.empty()) return;
  // Segments from the surface points A_i to the light B_i (all the same point for one light's
  // packet): every point is (1 - s) A_i + s B_i, inside the box swept from box(A) to box(B).
  // Lanes whose surface points lie far apart (a packet across a depth edge) are swept apart:
  // one sweep over all of them would be as wide as the gap all the way to the light. (The tile
  // kernels try the packet as one group first, shadow_box; they come here when it is not.)
  struct Cluster {
    glm::vec3 a_lo, a_hi, b_lo, b_hi;
  };
  Cluster clusters[32];
  int count = 0;
  for (int i = 0; i < n; ++i) {
    const glm::vec3& o = org[i];
    const glm::vec3& d = dir[i];
    if (!finite(o) || !finite(d) || !std::isfinite(t_end[i])) continue;
    const glm::vec3 b = o + d * t_end[i];
    if (!finite(b)) {  // past float's range: this one in double, on its own
      const glm::dvec3 bd = glm::dvec3(o) + glm::dvec3(d) * static_cast<double>(t_end[i]);
      mark_sweep(glm::dvec3(o), glm::dvec3(o), bd - 1e-6 * glm::length(bd), bd + 1e-6 * glm::length(bd));
      continue;
    }
    int c = 0;
    for (; c < count; ++c) {
      Cluster& k = clusters[c];
      const glm::vec3 a_lo = glm::min(k.a_lo, o), a_hi = glm::max(k.a_hi, o);
      const glm::vec3 b_lo = glm::min(k.b_lo, b), b_hi = glm::max(k.b_hi, b);
      if (one_group(a_lo, a_hi, b_lo, b_hi)) {
        k = Cluster{a_lo, a_hi, b_lo, b_hi};
        break;
      }
    }
    if (c == count) {
      if (count == static_cast<int>(std::size(clusters))) {
        Cluster& k = clusters[0];  // never with packets of at most 32 lanes
        k = Cluster{glm::min(k.a_lo, o), glm::max(k.a_hi, o), glm::min(k.b_lo, b), glm::max(k.b_hi, b)};
      } else {
        clusters[count++] = Cluster{o, o, b, b};
      }
    }
  }
  for (int c = 0; c < count; ++c) {
    const Cluster& k = clusters[c];
    // Every group fits the limit but the first one once all the others are full: as it is.
    if (!shadow_box(k.a_lo, k.a_hi, k.b_lo, k.b_hi)) add_float_sweep(k.a_lo, k.a_hi, k.b_lo, k.b_hi);
  }
}

void MarkRecorder::mark_sweep(const glm::dvec3& a_lo, const glm::dvec3& a_hi, const glm::dvec3& b_lo,
                              const glm::dvec3& b_hi) {
  DBox box_a, box_b;
  box_a.lo = a_lo, box_a.hi = a_hi, box_b.lo = b_lo, box_b.hi = b_hi;
  // The part of s in [0, 1] where the swept box meets the grid (its bounds are linear in s).
  double s0 = 0.0, s1 = 1.0;
  if (!meets_grid(box_a.lo, box_b.lo - box_a.lo, box_a.hi, box_b.hi - box_a.hi, s0, s1)) return;  // passes beside it
  // Widen a hair for the rounding of the divisions above.
  s0 = std::max(0.0, s0 - 1e-9);
  s1 = std::min(1.0, s1 + 1e-9);
  double cells = 0.0;
  for (int k = 0; k < 3; ++k) {
    cells = std::max(cells, std::max(std::abs(box_b.lo[k] - box_a.lo[k]), std::abs(box_b.hi[k] - box_a.hi[k])) *
                                inv_cell_[k]);
  }
  const int pieces = static_cast<int>(std::clamp(std::ceil(cells * (s1 - s0) * kPiecesPerCell), 1.0, 16.0 * kMaxMarkCellsPerAxis));
  auto lerp = [](const glm::dvec3& a, const glm::dvec3& b, double t) { return a + (b - a) * t; };
  glm::dvec3 lo0 = lerp(box_a.lo, box_b.lo, s0), hi0 = lerp(box_a.hi, box_b.hi, s0);
  for (int j = 1; j <= pieces; ++j) {
    const double s = j == pieces ? s1 : s0 + (s1 - s0) * j / pieces;
    const glm::dvec3 lo1 = s == 1.0 ? box_b.lo : lerp(box_a.lo, box_b.lo, s);
    const glm::dvec3 hi1 = s == 1.0 ? box_b.hi : lerp(box_a.hi, box_b.hi, s);
    mark_box(1, glm::min(lo0, lo1), glm::max(hi0, hi1));
    lo0 = lo1;
    hi0 = hi1;
  }
}

void MarkRecorder::take(TileMarks& out) {
  flush();
  for (int list = 0; list < 2; ++list) {
    std::vector<std::uint32_t>& dst = list == 0 ? out.path : out.shadow;
    dst.clear();
    std::vector<std::uint32_t>& touched = touched_[list];
    std::sort(touched.begin(), touched.end());
    for (const std::uint32_t w : touched) {
      std::uint64_t bits = bits_[list][w];
      bits_[list][w] = 0;
      while (bits != 0) {
        dst.push_back(w * 64u + static_cast<std::uint32_t>(std::countr_zero(bits)));
        bits &= bits - 1;
      }
    }
    touched.clear();
  }
  out.shaded = shaded_;
  shaded_ = false;
  for (int* last : last_box_) std::fill(last, last + 6, -1);
}

// ---- tracker --------------------------------------------------------------------------------

TemporalTracker::TemporalTracker(const Scene& scene, MarkGrid grid, std::uint32_t tiles)
    : scene_(&scene), grid_(grid), tiles_(tiles), words_((tiles + 63) / 64), records_(tiles) {
  check_mark_grid(grid_, "temporal coherence");
  voxel_tiles_[0].resize(grid_.voxel_count());
  voxel_tiles_[1].resize(grid_.voxel_count());
  mesh_lo_.resize(scene.meshes.size());
  mesh_hi_.resize(scene.meshes.size());
  mesh_radius_.resize(scene.meshes.size());
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const DBox b = object_bounds(scene.meshes[m]);
    mesh_lo_[m] = b.lo;
    mesh_hi_[m] = b.hi;
    mesh_radius_[m] = object_radius(scene.meshes[m]);
  }
}

void TemporalTracker::clear_marks(std::uint32_t tile) {
  TileRecord& r = records_[tile];
  const std::uint64_t mask = ~(std::uint64_t{1} << (tile & 63));
  for (int list = 0; list < 2; ++list) {
    for (const std::uint32_t v : list == 0 ? r.marks.path : r.marks.shadow) {
      std::vector<std::uint64_t>& t = voxel_tiles_[list][v];
      if (!t.empty()) t[tile >> 6] &= mask;
    }
  }
  r.marks = TileMarks{};
  r.known = false;
}

void TemporalTracker::set_marks(std::uint32_t tile, const TileMarks& marks) {
  TileRecord& r = records_[tile];
  const std::uint32_t voxels = grid_.voxel_count();
  for (int list = 0; list < 2; ++list) {
    for (const std::uint32_t v : list == 0 ? marks.path : marks.shadow) {
      if (v >= voxels) return;  // not this grid's: leave the tile unknown (traced again)
    }
  }
  r.marks = marks;
  for (int list = 0; list < 2; ++list) {
    for (const std::uint32_t v : list == 0 ? r.marks.path : r.marks.shadow) {
      std::vector<std::uint64_t>& t = voxel_tiles_[list][v];
      if (t.empty()) t.assign(words_, 0);
      t[tile >> 6] |= std::uint64_t{1} << (tile & 63);
    }
  }
  r.known = true;
}

void TemporalTracker::replace_marks(std::uint32_t tile, const TileMarks& marks) {
  TileRecord& r = records_[tile];
  const std::uint32_t voxels = grid_.voxel_count();
  const auto usable = [voxels](const std::vector<std::uint32_t>& list) {
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (list[i] >= voxels || (i > 0 && list[i] <= list[i - 1])) return false;
    }
    return true;
  };
  if (!r.known || !usable(marks.path) || !usable(marks.shadow)) {
    clear_marks(tile);
    set_marks(tile, marks);  // leaves the tile unknown when a voxel is not this grid's
    return;
  }
  // A tile traced again mostly crosses the voxels it crossed before: walk the old and new
  // lists (both ascending) and touch only the voxels in one of them (Jevans 3.3.1's reset, done
  // as a difference).
  const std::uint64_t bit = std::uint64_t{1} << (tile & 63);
  for (int list = 0; list < 2; ++list) {
    const std::vector<std::uint32_t>& old_list = list == 0 ? r.marks.path : r.marks.shadow;
    const std::vector<std::uint32_t>& new_list = list == 0 ? marks.path : marks.shadow;
    std::size_t i = 0, j = 0;
    while (i < old_list.size() || j < new_list.size()) {
      if (j == new_list.size() || (i < old_list.size() && old_list[i] < new_list[j])) {
        std::vector<std::uint64_t>& t = voxel_tiles_[list][old_list[i++]];
        if (!t.empty()) t[tile >> 6] &= ~bit;
      } else if (i == old_list.size() || new_list[j] < old_list[i]) {
        std::vector<std::uint64_t>& t = voxel_tiles_[list][new_list[j++]];
        if (t.empty()) t.assign(words_, 0);
        t[tile >> 6] |= bit;
      } else {
        ++i, ++j;
      }
    }
  }
  r.marks = marks;
}

bool TemporalTracker::must_trace(const TileRecord& r, const PlanData& d) const {
  if (d.full || !r.known) return true;
  if (d.lights_moved && r.marks.shaded) return true;
  for (const auto* list : {&r.marks.path, &r.marks.shadow}) {
    for (const std::uint32_t v : *list) {
      if ((d.changed[v >> 6] >> (v & 63)) & 1u) return true;
    }
  }
  return false;
}

std::vector<TemporalDecision> TemporalTracker::done(std::uint32_t tile, std::uint64_t id, const TileMarks* marks) {
  std::vector<TemporalDecision> decisions;
  if (tile >= tiles_ || records_[tile].out != id || id == 0) return decisions;  // not out for this plan
  TileRecord& r = records_[tile];
  r.out = 0;
  if (marks != nullptr) {
    replace_marks(tile, *marks);
  } else {
    clear_marks(tile);
  }
  std::size_t i = 0;
  for (; i < r.waiting.size(); ++i) {
    const std::uint64_t p = r.waiting[i];
    const auto it = plans_.find(p);
    const bool trace = it == plans_.end() || must_trace(r, it->second);
    decisions.push_back(TemporalDecision{p, tile, trace});
    if (it != plans_.end() && --it->second.waiting == 0) plans_.erase(it);
    if (trace) {
      r.out = p;
      ++i;
      break;
    }
  }
  r.waiting.erase(r.waiting.begin(), r.waiting.begin() + static_cast<std::ptrdiff_t>(i));
  return decisions;
}

bool TemporalTracker::mark_mesh(std::size_t mesh, const glm::mat4& world, std::vector<std::uint64_t>& changed) const {
  if (mesh >= scene_->meshes.size() || mesh_lo_[mesh].x > mesh_hi_[mesh].x) return true;  // no triangles
  if (grid_.empty()) return false;
  // The voxels each triangle's box touches: a ray sees the mesh only where it meets a triangle,
  // so its surface is what changed, not the space it encloses (a box around a whole moving mesh
  // marks about twice as many tiles on the office benchmark).
  const Mesh& m = scene_->meshes[mesh];
  const glm::dmat4 w(world);
  std::vector<glm::dvec3> p(m.positions.size());
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = glm::dvec3(w * glm::dvec4(glm::dvec3(m.positions[i]), 1.0));
  const glm::dvec3 cell = (grid_.hi - grid_.lo) / glm::dvec3(grid_.dims);
  DBox all;
  for (const glm::dvec3& q : p) all.extend(q);
  const double pad = pad_for(all, std::min({cell.x, cell.y, cell.z}));
  for (const glm::uvec3& t : m.triangles) {
    if (t.x >= p.size() || t.y >= p.size() || t.z >= p.size()) continue;
    DBox box;
    box.extend(p[t.x]);
    box.extend(p[t.y]);
    box.extend(p[t.z]);
    int lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      if (box.lo[k] < grid_.lo[k] || box.hi[k] > grid_.hi[k]) return false;
      lo[k] = std::clamp(static_cast<int>(std::floor((box.lo[k] - pad - grid_.lo[k]) / cell[k])), 0, grid_.dims[k] - 1);
      hi[k] = std::clamp(static_cast<int>(std::floor((box.hi[k] + pad - grid_.lo[k]) / cell[k])), 0, grid_.dims[k] - 1);
    }
    for (int z = lo[2]; z <= hi[2]; ++z) {
      for (int y = lo[1]; y <= hi[1]; ++y) {
        for (int x = lo[0]; x <= hi[0]; ++x) {
          const auto v = static_cast<std::uint32_t>(x + grid_.dims.x * (y + grid_.dims.y * z));
          changed[v >> 6] |= std::uint64_t{1} << (v & 63);
        }
      }
    }
  }
  return true;
}

TemporalPlan TemporalTracker::plan(int frame) {
  TemporalPlan p;
  p.id = next_plan_++;
  p.dirty.assign(tiles_, TemporalPlan::kKeep);
  const FramePose pose = pose_at(*scene_, frame);
  PlanData data;
  data.changed.assign((grid_.voxel_count() + 63) / 64, 0);
  std::uint32_t meshes_moved = 0, lights_moved = 0;
  if (!have_last_) {
    data.full = true;
    p.why = "first frame";
  } else if (!(pose.camera == last_.camera)) {
    data.full = true;
    p.why = "camera moved: every tile traced";
  } else {
    for (std::size_t m = 0; m < pose.world_from_object.size() && m < last_.world_from_object.size(); ++m) {
      if (pose.world_from_object[m] == last_.world_from_object[m]) continue;
      ++meshes_moved;
      if (!mark_mesh(m, last_.world_from_object[m], data.changed) || !mark_mesh(m, pose.world_from_object[m], data.changed)) {
        data.full = true;
        p.why = "mesh " + std::to_string(m) + " moved outside the mark grid: every tile traced";
        break;
      }
    }
    for (std::size_t l = 0; l < pose.lights.size() && l < last_.lights.size(); ++l) {
      lights_moved += pose.lights[l] == last_.lights[l] ? 0 : 1;
    }
    data.lights_moved = lights_moved > 0;
    if (!data.full) {
      p.why = std::to_string(meshes_moved) + (meshes_moved == 1 ? " mesh" : " meshes") + " and " +
              std::to_string(lights_moved) + (lights_moved == 1 ? " light" : " lights") + " moved";
    }
  }
  p.full = data.full;
  // Tiles whose rays crossed a changed voxel, from the bit tables (path and shadow apart).
  std::vector<std::uint64_t> dirty_path(words_, 0), dirty_shadow(words_, 0);
  if (!data.full) {
    for (std::size_t w = 0; w < data.changed.size(); ++w) {
      std::uint64_t bits = data.changed[w];
      while (bits != 0) {
        const std::size_t v = w * 64 + static_cast<std::size_t>(std::countr_zero(bits));
        bits &= bits - 1;
        ++p.changed_voxels;
        for (int list = 0; list < 2; ++list) {
          const std::vector<std::uint64_t>& t = voxel_tiles_[list][v];
          std::vector<std::uint64_t>& dst = list == 0 ? dirty_path : dirty_shadow;
          for (std::size_t i = 0; i < t.size(); ++i) dst[i] |= t[i];
        }
      }
    }
  }
  for (std::uint32_t tile = 0; tile < tiles_; ++tile) {
    TileRecord& r = records_[tile];
    if (r.out != 0 || !r.waiting.empty()) {
      p.dirty[tile] = TemporalPlan::kWait;
      r.waiting.push_back(p.id);
      ++data.waiting;
      ++p.waiting;
      continue;
    }
    const std::uint64_t bit = std::uint64_t{1} << (tile & 63);
    bool trace = data.full;
    if (!r.known) {
      ++p.unknown;
      trace = true;
    }
    if (dirty_path[tile >> 6] & bit) {
      ++p.by_path;
      trace = true;
    }
    if (dirty_shadow[tile >> 6] & bit) {
      ++p.by_shadow;
      trace = true;
    }
    if (data.lights_moved && r.marks.shaded) {
      ++p.by_light;
      trace = true;
    }
    if (trace) {
      p.dirty[tile] = TemporalPlan::kTrace;
      r.out = p.id;
      ++p.dirty_count;
    }
  }
  if (data.waiting > 0) plans_.emplace(p.id, std::move(data));
  last_ = pose;
  have_last_ = true;
  return p;
}

}  // namespace rtc
