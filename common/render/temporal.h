// Object-space temporal coherence (Jevans 1992, "Object Space Temporal Coherence for Ray
// Tracing"): while a frame is traced, every tile records which voxels of a coarse grid its rays
// crossed; when the next frame moves some meshes (the camera staying put), only the tiles whose
// rays crossed a voxel a moving mesh left or entered are traced again, the others keep their
// pixels. The result is bit-identical to tracing every tile again.
//
// Why a grid of its own and not the kd-tree's leaves: the tree of a frame whose meshes moved is
// a different tree, so its leaves cannot name the same space from one frame to the next; the
// grid is fixed for the whole animation. It covers only the region that moving meshes can reach
// over the animation (the union of their bounds between consecutive keys): a ray that never
// enters that region cannot change however the meshes move, so it costs one box test and
// records nothing.
//
// The pieces: MarkGrid (the voxels), MarkRecorder (what the tile kernels call per ray segment),
// TileMarks (one tile's record, which a worker sends to the master), TemporalTracker (per-voxel
// bit tables of tiles and the dirty-tile plan for each frame; the master keeps it, and
// rtc-render locally). Pure functions of the scene, so master and workers agree.
#pragma once

#include <climits>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "common/scene/scene.h"

namespace rtc {

/// Whether to use temporal coherence: Auto = on unless the camera moves over the frames
/// rendered (every frame would be traced whole anyway, the marks would be wasted work).
enum class TemporalMode : std::uint8_t { Auto, On, Off };
/// "auto", "on", "off"; parse_temporal_mode throws rtc::Error naming the value.
[[nodiscard]] const char* temporal_mode_name(TemporalMode mode);
[[nodiscard]] TemporalMode parse_temporal_mode(const std::string& text);
/// Frames [first_frame, last_frame] are rendered (the defaults: every frame of the animation).
/// Auto is on when the camera is the same at first_frame, last_frame and every camera key
/// between them; a camera that moves only outside those frames does not count.
/// With `loop` (rtc-master --loop, a frame-rate run), Auto is also off when nothing at all
/// moves over the frames: every frame after the first would cost nothing, and the rate said
/// nothing (41,002 frames a second of a still scene).
[[nodiscard]] bool temporal_for(const Scene& scene, TemporalMode mode, int first_frame = INT_MIN,
                                int last_frame = INT_MAX, bool loop = false);
/// Whether the camera, a mesh or a light moves over frames [first_frame, last_frame].
[[nodiscard]] bool anything_moves(const Scene& scene, int first_frame, int last_frame);

/// temporal_for for a run of frames [first_frame, last_frame] (or a --loop over them), with the
/// reason when it is off, for the log: "--temporal off", "one frame", "the camera moves over the
/// frames rendered", "--loop over frames where nothing moves: ...". Decided once per run and
/// passed on, so that a program's tile size and its tracker cannot disagree.
struct TemporalChoice {
  bool on = false;
  std::string why_off;  ///< empty when on
  bool moves = true;    ///< anything_moves over the frames (on, and false: nothing is ever retraced)
};
[[nodiscard]] TemporalChoice choose_temporal(const Scene& scene, TemporalMode mode, int first_frame, int last_frame,
                                             bool loop = false);

/// A voxel grid over [lo, hi] with dims cells per axis; empty (dims 0) when no mesh moves.
struct MarkGrid {
  glm::dvec3 lo{0.0};
  glm::dvec3 hi{0.0};
  glm::ivec3 dims{0};

  [[nodiscard]] bool empty() const { return dims.x <= 0 || dims.y <= 0 || dims.z <= 0; }
  [[nodiscard]] std::uint32_t voxel_count() const {
    return empty() ? 0u : static_cast<std::uint32_t>(dims.x) * static_cast<std::uint32_t>(dims.y) *
                              static_cast<std::uint32_t>(dims.z);
  }
  bool operator==(const MarkGrid&) const = default;
};

/// Cells along the grid's longest axis by default (the others get cells of about the same size).
inline constexpr int kDefaultMarkCells = 24;
/// Tile size rtc-render and rtc-master use when temporal coherence is on and --tile is not
/// given: the tile is the unit retraced, and the pixels near a moving mesh cost the most, so
/// finer tiles leave out more of the cheap ones around them (office_mover: 16% of the pixels
/// retraced per frame instead of 22%, frames 1.2x faster; tests/bench/results/temporal.md).
inline constexpr int kTemporalTileSize = 16;
/// Largest cells per axis and voxels a grid may have (MarkGrid messages are checked against it).
inline constexpr int kMaxMarkCellsPerAxis = 256;
inline constexpr std::uint32_t kMaxMarkVoxels = 1u << 21;

/// Throws rtc::Error naming `what` unless the grid is empty or finite with lo < hi, dims in
/// [1, kMaxMarkCellsPerAxis] and at most kMaxMarkVoxels voxels.
void check_mark_grid(const MarkGrid& grid, const std::string& what);

/// The region the scene's moving meshes can occupy over frames [first_frame, last_frame]
/// (the defaults: the whole animation, held poses before the first key and after the last
/// included), padded, split into about `cells` voxels along its longest axis, fewer where that
/// would make more than kMaxMarkVoxels voxels. Empty when no mesh moves over those frames. Keys
/// outside the frames do not widen it (a key at frame 1000 far away made every voxel of a
/// 10-frame run 25 units wide); a mesh that leaves it anyway makes its frame traced whole.
[[nodiscard]] MarkGrid mark_grid_for(const Scene& scene, int cells = kDefaultMarkCells, int first_frame = INT_MIN,
                                     int last_frame = INT_MAX);

/// What the rays of one tile crossed: voxel indices (x + dims.x * (y + dims.y * z)), sorted
/// and unique.
struct TileMarks {
  std::vector<std::uint32_t> path;    ///< primary and reflection rays, up to their hit
  std::vector<std::uint32_t> shadow;  ///< shadow rays, from the surface to the light
  bool shaded = false;  ///< some hit was shaded with the lights (so it changes when a light moves)
  bool operator==(const TileMarks&) const = default;
};

/// Records the voxels one tile's rays cross (one recorder per thread; not thread-safe).
///
/// Rays come in groups (a packet's lanes) and are marked a group at a time, at a fraction of
/// the cost of walking every ray through the grid (a per-ray walk measured 2.3x the trace time
/// on the built-in scene):
/// - path rays (primary, reflection): at a common t every ray lies in box(org) + t box(dir),
///   so the voxels of that box, for t in pieces that each move about a cell, cover them: a thin
///   tube for a coherent packet whatever its rays' lengths (a ray that stopped early is carried
///   on to the longest one's end, a little more than it crossed);
/// - shadow rays: every point is (1 - s) A_i + s B_i between the surface point A_i and the light
///   B_i (one point for a packet), inside the box swept from box(A) to box(B); the lanes are
///   first gathered into groups whose surface points lie within a cell of each other, so a
///   packet across a depth edge sweeps two thin boxes, not one as wide as the gap (on the office
///   benchmark that cut the shadow voxels marked 10-30x and the tiles retraced by a fifth).
/// Conservative: every voxel a ray crosses is marked (and some beside it); boxes are padded
/// beyond float rounding, and so are the changed voxels (TemporalTracker).
class MarkRecorder {
 public:
  explicit MarkRecorder(const MarkGrid& grid);
  /// Segments org_i + t dir_i, t in [0, t_end_i] (t_end may be infinite), of one group.
  void path(int n, const glm::vec3* org, const glm::vec3* dir, const float* t_end) { path_group(n, org, dir, t_end); }
  /// Shadow segments, t in [0, t_end_i] (finite; the light at t_end).
  void shadow(int n, const glm::vec3* org, const glm::vec3* dir, const float* t_end) { shadow_group(n, org, dir, t_end); }
  /// The same for a group the caller has already reduced to boxes (the kernels do it with SIMD):
  /// its rays' origins in [o_lo, o_hi], directions in [d_lo, d_hi], the longest t_end t_max,
  /// every value finite but t_max. False when the group must be marked ray by ray (a tube
  /// unbounded in every axis): call path() with the rays then.
  [[nodiscard]] bool path_box(const glm::vec3& o_lo, const glm::vec3& o_hi, const glm::vec3& d_lo,
                              const glm::vec3& d_hi, float t_max);
  /// Shadow segments from surface points in [a_lo, a_hi] to ends in [b_lo, b_hi] (the ends as
  /// org + dir * t_end in float). False when the boxes are wider than one group or not finite:
  /// call shadow() with the rays then.
  [[nodiscard]] bool shadow_box(const glm::vec3& a_lo, const glm::vec3& a_hi, const glm::vec3& b_lo,
                                const glm::vec3& b_hi);
  void shaded() { shaded_ = true; }
  [[nodiscard]] bool grid_empty() const { return grid_.empty(); }
  /// Moves the record into `out` and starts a new one.
  void take(TileMarks& out);

 private:
  void path_group(int n, const glm::vec3* org, const glm::vec3* dir, const float* t_end);
  void shadow_group(int n, const glm::vec3* org, const glm::vec3* dir, const float* t_end);
  void mark_box(int list, const glm::dvec3& lo, const glm::dvec3& hi);
  /// Narrows [t0, t1] to where the box [lo_at_0 + t lo_slope, hi_at_0 + t hi_slope] (padded)
  /// meets the grid; false when it never does there. Path tubes (t along the rays) and shadow
  /// sweeps (t from the surface to the light) both have bounds linear in t.
  [[nodiscard]] bool meets_grid(const glm::dvec3& lo_at_0, const glm::dvec3& lo_slope, const glm::dvec3& hi_at_0,
                                const glm::dvec3& hi_slope, double& t0, double& t1) const;
  /// Groups waiting to be marked, merged with the next ones while they run side by side.
  void add_tube(const glm::dvec3& o_lo, const glm::dvec3& o_hi, const glm::dvec3& d_lo, const glm::dvec3& d_hi,
                double t_lo, double t_hi);
  void add_sweep(const glm::dvec3& a_lo, const glm::dvec3& a_hi, const glm::dvec3& b_lo, const glm::dvec3& b_hi);
  /// Whether shadow rays with surface points in [a_lo, a_hi] and ends in [b_lo, b_hi] are close
  /// enough to be swept as one group (kClusterCells per axis).
  [[nodiscard]] bool one_group(const glm::vec3& a_lo, const glm::vec3& a_hi, const glm::vec3& b_lo,
                               const glm::vec3& b_hi) const;
  /// add_sweep of float boxes, the light ends padded past the rounding of org + dir * t_end.
  void add_float_sweep(const glm::vec3& a_lo, const glm::vec3& a_hi, const glm::vec3& b_lo, const glm::vec3& b_hi);
  void flush();
  /// Shadow marks of the box swept from [a_lo, a_hi] to [b_lo, b_hi].
  void mark_sweep(const glm::dvec3& a_lo, const glm::dvec3& a_hi, const glm::dvec3& b_lo, const glm::dvec3& b_hi);
  /// Path marks of box(org) + t box(dir) for t in [t_lo, t_hi] (t_lo >= 0, finite).
  void mark_tube(const glm::dvec3& o_lo, const glm::dvec3& o_hi, const glm::dvec3& d_lo, const glm::dvec3& d_hi,
                 double t_lo, double t_hi);

  MarkGrid grid_;
  glm::dvec3 cell_{0.0};
  glm::dvec3 inv_cell_{0.0};
  double pad_ = 0.0;
  std::vector<std::uint64_t> bits_[2];
  std::vector<std::uint32_t> touched_[2];  ///< indices of non-zero words of bits_
  int last_box_[2][6] = {{-1, -1, -1, -1, -1, -1}, {-1, -1, -1, -1, -1, -1}};  ///< voxel range marked last, per list
  bool shaded_ = false;
  struct Tube {
    bool live = false;
    glm::dvec3 o_lo{0.0}, o_hi{0.0}, d_lo{0.0}, d_hi{0.0};
    double t_lo = 0.0, t_hi = 0.0;
  } tube_;
  struct Sweep {
    bool live = false;
    glm::dvec3 a_lo{0.0}, a_hi{0.0}, b_lo{0.0}, b_hi{0.0};
  } sweeps_[4];
  int next_sweep_ = 0;
};

/// Which tiles of the next frame must be traced, and why.
struct TemporalPlan {
  static constexpr std::uint8_t kKeep = 0;   ///< keep the pixels of the tile's last trace
  static constexpr std::uint8_t kTrace = 1;  ///< trace it
  static constexpr std::uint8_t kWait = 2;   ///< undecided: an earlier trace of it is still out
  std::uint64_t id = 0;              ///< give it back to TemporalTracker::done
  std::vector<std::uint8_t> dirty;   ///< per tile: kKeep, kTrace or kWait
  std::uint32_t dirty_count = 0;     ///< kTrace tiles
  std::uint32_t waiting = 0;         ///< kWait tiles (decided later by done())
  bool full = false;                 ///< every tile (first frame, camera moved, ...)
  std::string why;                   ///< e.g. "first frame", "camera moved", "1 mesh and 0 lights moved"
  std::uint32_t changed_voxels = 0;
  std::uint32_t by_path = 0, by_shadow = 0, by_light = 0, unknown = 0;  ///< kTrace for each reason (overlapping)
};

/// A decision done() made for a tile that a later plan left waiting.
struct TemporalDecision {
  std::uint64_t plan = 0;
  std::uint32_t tile = 0;
  bool trace = false;  ///< true: trace it for that plan; false: it keeps the pixels just traced
};

/// The bookkeeping: per tile its last marks, per voxel a bit table of the tiles whose rays
/// crossed it (path and shadow kept apart), and the pose of the last frame planned. Not
/// thread-safe. Tiles are numbered 0..tiles-1 by the caller.
///
/// Frames in flight: a tile still being traced for an earlier frame has no marks yet, so a
/// later plan leaves it waiting (kWait) instead of tracing it again on suspicion; when the
/// trace reports, done() decides every plan waiting on it, in order, with the new marks. A
/// tile is therefore out for one frame at a time.
class TemporalTracker {
 public:
  TemporalTracker(const Scene& scene, MarkGrid grid, std::uint32_t tiles);

  [[nodiscard]] const MarkGrid& grid() const { return grid_; }
  [[nodiscard]] std::uint32_t tiles() const { return tiles_; }

  /// Plans `frame` against the last frame planned: a tile is traced when its last trace left
  /// no marks, when its rays crossed a voxel that a moved mesh occupied in either frame, or
  /// when a light moved and it shaded a hit; everything is traced on the first call and when
  /// the camera changed. The kTrace tiles are out until done() is called with this plan's id.
  [[nodiscard]] TemporalPlan plan(int frame);
  /// The trace of `tile` for plan `id` finished with these marks (null: unknown, e.g. a peer
  /// that sent none, or a trace that never reports: the tile is traced next time). Resets the
  /// tile's old marks first (Jevans 3.3.1), then decides the plans waiting on the tile.
  /// Returns those decisions in plan order (at most one of them traces).
  std::vector<TemporalDecision> done(std::uint32_t tile, std::uint64_t id, const TileMarks* marks);

 private:
  struct TileRecord {
    TileMarks marks;
    bool known = false;               ///< marks describe the tile's last trace
    std::uint64_t out = 0;            ///< plan id of the trace in flight, 0: none
    std::vector<std::uint64_t> waiting;  ///< plans waiting on it, ascending
  };
  struct PlanData {  ///< what a plan changed, kept while tiles wait on it
    bool full = false;
    bool lights_moved = false;
    std::vector<std::uint64_t> changed;  ///< voxel bits
    std::uint32_t waiting = 0;
  };
  void clear_marks(std::uint32_t tile);
  void set_marks(std::uint32_t tile, const TileMarks& marks);
  /// clear_marks then set_marks, touching only the voxels whose bit changes.
  void replace_marks(std::uint32_t tile, const TileMarks& marks);
  [[nodiscard]] bool must_trace(const TileRecord& r, const PlanData& d) const;
  /// Voxels that mesh `mesh` covers under `world` (padded), OR'ed into `changed`; false when the
  /// box is not inside the grid.
  bool mark_mesh(std::size_t mesh, const glm::mat4& world, std::vector<std::uint64_t>& changed) const;

  const Scene* scene_;
  MarkGrid grid_;
  std::uint32_t tiles_ = 0;
  std::uint32_t words_ = 0;  ///< 64-bit words per tile bit table
  std::vector<TileRecord> records_;
  /// voxel -> bit table of tiles (words_ words), allocated on first use; [0] path, [1] shadow.
  std::vector<std::vector<std::uint64_t>> voxel_tiles_[2];
  std::vector<glm::dvec3> mesh_lo_, mesh_hi_;  ///< object-space bounds per mesh
  std::vector<double> mesh_radius_;            ///< largest |vertex| per mesh, object space
  std::map<std::uint64_t, PlanData> plans_;    ///< plans with waiting tiles
  bool have_last_ = false;
  FramePose last_;
  std::uint64_t next_plan_ = 1;
};

}  // namespace rtc
