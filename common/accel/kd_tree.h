// SAH kd-tree over a triangle array, with Wald's 8-byte nodes and 48-byte triangle records
// (Wald, Slusallek, Benthin, Wagner 2001, sections 2.1-2.2), or optionally watertight records
// holding the vertices for Woop, Benthin and Wald's test (2013).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <new>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <glm/glm.hpp>

#include "common/base/error.h"
#include "common/base/isa.h"
#include "common/math/aabb.h"

namespace rtc {

/// 8 bytes. Inner node: bits = (index of the left child << 5) | (denser child << 4) | (empty
/// children << 2) | axis (0, 1, 2), children adjacent (right = left + 1), `split` the plane
/// position; bit c of the empty children (bits 2-3) is set when child left + c is a leaf
/// without triangles, so a walk can pass it by without loading it; the denser child (bit 4,
/// denser()) is the one a ray crossing the node more likely stops in, by the build's estimate
/// (KdBuildOptions::mark_denser), which the dense shadow order enters first. Leaf: bits =
/// (offset into KdTree::prim_refs << 2) | 3, `count` the number of triangle references
/// (tri_count()) with kLeafTag set (in every leaf KdNode::leaf() makes; the default KdNode, an
/// empty leaf, has 0), and kBoxed when the slot before the first holds the leaf's LeafBox
/// (has_box()).
struct KdNode {
  std::uint32_t bits = 3;
  union {
    float split;
    std::uint32_t count = 0;
  };

  /// The most nodes a tree may have: inner nodes keep 27 bits for the left child's index.
  static constexpr std::uint64_t kMaxNodes = std::uint64_t{1} << 27;
  /// A leaf's `count` bit that says it has a LeafBox (counts stay below 2^30).
  static constexpr std::uint32_t kBoxed = 1u << 31;
  /// A bit set in every leaf's `count` that KdNode::leaf() makes, so that the word read as a
  /// float (`split`) is never a denormal: its exponent field is 0x80 or more (a normal number
  /// of magnitude at least 2, negative with kBoxed; not finite from 2^30 - 2^23 references on,
  /// past any real leaf). The single-ray walk computes a plane distance from both children's
  /// second words before it knows which is a leaf (kd_traverse.h); a non-empty leaf's bare count
  /// read as a float is a denormal, and on AMD's Zen 5 every operation on one took a microcode
  /// assist: with this bit, single rays 1.08-1.95x as fast on six large views (medians 1.59
  /// closest hit, 1.56 occlusion) and 2.9x on spd-tree's ground; packets unchanged
  /// (trace_experiments.md, session 46).
  static constexpr std::uint32_t kLeafTag = 1u << 30;

  /// An inner node over children left and left + 1, marking those that are empty leaves.
  [[nodiscard]] static KdNode inner(std::uint64_t left, int axis, float split, bool left_empty = false,
                                    bool right_empty = false) {
    KdNode n;
    n.bits = (static_cast<std::uint32_t>(left) << 5) | (left_empty ? 4u : 0u) | (right_empty ? 8u : 0u) |
             static_cast<std::uint32_t>(axis);
    n.split = split;
    return n;
  }
  /// A leaf over `count` references from prim_refs[offset]; `boxed`: with its LeafBox at
  /// offset - 1.
  [[nodiscard]] static KdNode leaf(std::uint64_t offset, std::uint32_t count, bool boxed = false) {
    KdNode n;
    n.bits = (static_cast<std::uint32_t>(offset) << 2) | 3u;
    RTC_DCHECK(count < kLeafTag, "KdNode::leaf: 2^30 references or more (the build keeps fewer triangles)");
    n.count = count | kLeafTag | (boxed ? kBoxed : 0u);
    return n;
  }

  [[nodiscard]] bool is_leaf() const { return (bits & 3u) == 3u; }
  [[nodiscard]] bool is_empty_leaf() const { return is_leaf() && tri_count() == 0; }
  [[nodiscard]] int axis() const { return static_cast<int>(bits & 3u); }
  [[nodiscard]] std::uint32_t left() const { return bits >> 5; }
  /// Inner nodes: which child (0: left, 1: right) a ray crossing the node more likely stops in.
  [[nodiscard]] std::uint32_t denser() const { return (bits >> 4) & 1u; }
  void set_denser(std::uint32_t c) { bits = (bits & ~16u) | ((c & 1u) << 4); }
  /// Inner nodes: whether child left() + c (c = 0, 1) is an empty leaf.
  [[nodiscard]] bool child_empty(std::uint32_t c) const { return (bits & (4u << c)) != 0; }
  [[nodiscard]] std::uint32_t prim_offset() const { return bits >> 2; }
  /// Leaves: the number of triangle references.
  [[nodiscard]] std::uint32_t tri_count() const { return count & ~(kBoxed | kLeafTag); }
  /// Leaves: whether the slot before the first reference holds the leaf's LeafBox.
  [[nodiscard]] bool has_box() const { return (count & kBoxed) != 0; }
};
static_assert(sizeof(KdNode) == 8);

/// Wald's projected-barycentric triangle record, 48 bytes (three 16-byte rows). The plane is
/// n_k x_k + n_u x_u + n_v x_v = n_d with n_k = 1, k the dominant normal axis, u = (k+1)%3,
/// v = (k+2)%3; beta = b_nu*h_u + b_nv*h_v + b_d and gamma = c_nu*h_u + c_nv*h_v + c_d are the
/// barycentric weights of vertices 1 and 2 for the projected hit point h.
struct alignas(16) TriAccel {
  float n_u = 0, n_v = 0, n_d = 0;
  std::uint32_t k = 3;  ///< 3 marks a degenerate triangle that never hits
  float b_nu = 0, b_nv = 0, b_d = 0;
  std::uint32_t id = 0;  ///< the triangle's id: its index in the arrays given to KdTree::build, or ids[index]
  float c_nu = 0, c_nv = 0, c_d = 0;
  std::uint32_t pad1 = 0;
};
static_assert(sizeof(TriAccel) == 48);

/// Woop, Benthin and Wald's watertight record (2013, "Watertight Ray/Triangle Intersection",
/// JCGT 2(1)), 48 bytes: the three vertices as given. Its members have the types of TriAccel's
/// in the same order, so the two are layout-compatible: `k` and `id` sit at the same offsets
/// (12 and 28) and, through TriRecord, read the same in either format.
/// Trivially default-constructible (no member initialisers) so that it can share TriRecord
/// with TriAccel; make_tri_verts fills every member.
struct alignas(16) TriVerts {
  float ax, ay, az;
  std::uint32_t k;  ///< 3 marks a degenerate triangle (never in the tree); 0 otherwise
  float bx, by, bz;
  std::uint32_t id;  ///< as TriAccel::id
  float cx, cy, cz;
  std::uint32_t pad1;
};
static_assert(sizeof(TriVerts) == 48);
static_assert(std::is_layout_compatible_v<TriVerts, TriAccel>);
static_assert(offsetof(TriVerts, k) == offsetof(TriAccel, k) && offsetof(TriVerts, id) == offsetof(TriAccel, id));

/// The slot before a leaf's first triangle record in leaves where it pays
/// (KdBuildOptions::leaf_box_saving; KdNode::has_box()): a box around the parts of the leaf's
/// triangles inside its cell, slightly widened (KdTree::build). A ray that misses it hits none
/// of them there, and the walks skip their tests. Layout-compatible with TriAccel, so `k` (3)
/// and `id` (kLeafBoxRef) read alike in every slot; it is never tested as a triangle.
struct alignas(16) LeafBox {
  float lo_x, lo_y, lo_z;
  std::uint32_t k;
  float hi_x, hi_y, hi_z;
  std::uint32_t id;
  float pad_x, pad_y, pad_z;
  std::uint32_t pad1;
};
static_assert(sizeof(LeafBox) == 48);
static_assert(std::is_layout_compatible_v<LeafBox, TriAccel>);

/// KdTree::prim_refs() entry of a slot that holds a LeafBox, not a triangle.
inline constexpr std::uint32_t kLeafBoxRef = 0xFFFFFFFFu;

/// One 48-byte slot: `wald` in trees built with KdBuildOptions::watertight = false,
/// `watertight` otherwise (KdTree::watertight() says which), or `box` before a leaf's triangles
/// (LeafBox). The three structs are layout-compatible (same member types in the same order), so
/// by the common-initial-sequence rule `wald.k` and `wald.id` may be read whichever member holds
/// the record.
union TriRecord {
  TriAccel wald = {};
  TriVerts watertight;
  LeafBox box;
};
static_assert(sizeof(TriRecord) == 48 && alignof(TriRecord) == 16);

/// `bytes` (> 0) aligned to `align` (a power of two), uninitialised; give back with free_pages
/// (the same `bytes` and `align`). Blocks of 2 MiB or more are aligned to 2 MiB and asked for as
/// transparent huge pages (madvise(MADV_HUGEPAGE); nothing changes where THP is off): their
/// first touches then fault once per 2 MiB, not once per 4 KiB. Such blocks that free_pages
/// took back are reused first (see free_pages). Throws std::bad_alloc.
void* alloc_pages(std::size_t bytes, std::size_t align);

/// Gives back a block of alloc_pages. One of 2 MiB or more is kept, and lent again for a request
/// of at least half its size, up to kPageCacheBlocks blocks and kPageCacheBytes bytes (beyond
/// them the oldest kept is freed): a tree is rebuilt frame after frame for moving meshes, and
/// the kernel zeroes every fresh page, 7% of spd-rings' build at 2 threads (its build's arrays
/// of 2 MiB or more: 240 MB). 16 blocks, not 8: repeated builds at 2 threads 0.975x (spd-rings)
/// and 0.983x (spd-mount-s10) the time (build_experiments.md, session 39). Smaller blocks go
/// back to malloc at once.
void free_pages(void* p, std::size_t bytes, std::size_t align) noexcept;
inline constexpr std::size_t kPageCacheBlocks = 16;
inline constexpr std::size_t kPageCacheBytes = std::size_t{1} << 30;

/// What free_pages keeps now, and how many alloc_pages calls it served since the process began.
struct PageCacheStats {
  std::size_t blocks = 0;
  std::size_t bytes = 0;
  std::uint64_t reused = 0;
};
[[nodiscard]] PageCacheStats page_cache_stats();

/// Frees every block free_pages keeps (a long-running process done with large scenes may call
/// it; nothing else needs to).
void release_page_cache() noexcept;

/// A fixed-size array of a trivially copyable T whose elements are not initialised on
/// allocation: the build writes each once, in parallel (value-initialising a vector of 48-byte
/// records wrote up to ~150 MB serially before the parallel fill). Large arrays get huge pages
/// (alloc_pages).
template <typename T>
class RawArray {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  RawArray() = default;
  explicit RawArray(std::size_t n)
      : data_(n > 0 ? static_cast<T*>(alloc_pages(n * sizeof(T), alignof(T))) : nullptr, Free{n * sizeof(T)}),
        size_(n) {}
  [[nodiscard]] T* data() { return data_.get(); }
  [[nodiscard]] const T* data() const { return data_.get(); }
  [[nodiscard]] std::size_t size() const { return size_; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  [[nodiscard]] std::span<const T> span() const { return {data_.get(), size_}; }

 private:
  struct Free {
    std::size_t bytes = 0;
    void operator()(T* p) const { free_pages(p, bytes, alignof(T)); }
  };
  std::unique_ptr<T[], Free> data_;
  std::size_t size_ = 0;
};

/// Build parameters: the SAH cost model (Wald & Havran 2006) and termination limits.
struct KdBuildOptions {
  /// K_T, cost of one traversal step. 3 (measured at K_I = 1.5): over the 16 shared views the
  /// same trace speed as 2 (16-wide primary rays 1.02x, shadow rays 1.05x, medians) with 40%
  /// fewer nodes and builds 0.67-0.91x the time (tests/bench/results/kd_cost.md); 2 had been
  /// measured faster than 1.
  float traversal_cost = 3.0f;
  /// K_I, cost of one triangle test. 1 (K_T/K_I = 3): against 1.5, over the 16 shared views
  /// 16-wide primary rays 1.03x and shadow rays 1.01x (medians; the big scenes where rtc trails
  /// Embree 1.09-1.16x), 24-64% fewer nodes, builds 0.91x (tests/bench/results/kd_ki.md); 0.75
  /// measured no better (kd_ki_075.md).
  float intersection_cost = 1.0f;
  float empty_bonus = 0.2f;        ///< cost reduction for splits that cut off empty space
  /// A node of the event sweep (more than mask_below references) whose references leave at
  /// least this fraction of its cell empty on one side of one axis is cut there at once, at
  /// its references' bound, without the SAH sweep over its planes (the widest such gap first;
  /// where the SAH would rather make the node a leaf than take that cut, the sweep decides as
  /// usual). A cut takes a level of the depth limit like any other. Above 1: off, every node
  /// swept. 0.2: against off, spd-tree builds in 0.84-0.89x the time (one thread, two, first
  /// builds) with 25% fewer nodes and the same SAH cost; the other views' builds take 0.89-1.04x
  /// (one thread: medians 0.95-0.96x in three runs), spd-balls' SAH cost rises 15% with the same
  /// trace speed. Trace speed is unchanged: 16-wide packets 0.98-1.06x over the 16 shared views
  /// (medians 1.004 primary, 1.001 shadow, paired within one process), 0.99-1.02x on close-ups
  /// of five large scenes (tests/bench/results/kd_empty_cut.md, kd_empty_cut_close.md). 0.1 lost
  /// 3-5% on spd-rings and spd-balls; 0.3 built spd-tree in 0.96x the time at 2 threads, against
  /// 0.89x at 0.2 (build_experiments.md, session 29).
  float empty_cut = 0.2f;
  int max_depth = 0;               ///< 0: 8 + 1.3 log2(N), at most 60
  int leaf_size = 1;               ///< nodes with this many triangles or fewer become leaves
  /// A leaf gets a box around its triangles' parts in its cell (LeafBox, in the slot before its
  /// first record), tested before the triangles, where that saves at least this many triangle
  /// tests per visit by the SAH's estimate: count x (1 - area(box) / area(cell)), the triangles
  /// times the chance that a ray crossing the cell misses the box. 0: no boxes.
  float leaf_box_saving = 2.0f;
  /// Subtrees of at most this many references (0 to 256: one to four 64-bit words) are built
  /// with bit masks over their references (Zhou, Hou, Wang, Guo 2008, section 4.3): each node's
  /// SAH counts are popcounts against masks computed once at the subtree's root. The same SAH
  /// and planes as the event sweep except that straddling triangles are not clipped again below
  /// that root (the tree is identical with clip off). 0: the event sweep down to the leaves.
  /// -1 (the default): effective_mask_below().
  int mask_below = -1;
  /// Nodes of more references than this are split with the binned SAH (256 bins per axis, the
  /// best plane refined to an exact one) in parallel; smaller ones are blocks, built with the
  /// exact event sweep (and the bit masks below mask_below), their large nodes' children side
  /// by side where a block is a large part of the scene. 4096: 2048 and 8192 built within 4%
  /// of it, 8192 0.94-1.26x the time over the 16 views with the same trace speed; 1024 and 512
  /// build the small scenes' trees from several blocks, but trace them slower on some views
  /// (16-wide packets 0.88-1.09x and 0.81-1.03x over ten small and medium views, spd-tetra-s8
  /// and spd-gears' shadow rays the worst; tests/bench/results/exact_below_1024_small.md).
  /// A scene of at most this many triangles is one block unless binned_root_above bins its root.
  int exact_below = 4096;
  /// The root is split with the binned SAH (as above exact_below) when it holds more than this
  /// many references, so that a scene of one block (at most exact_below triangles) starts as
  /// two blocks that build side by side: the one block's set-up, root sweep and root split ran
  /// before its first fork, mostly on one thread (bunny at 2 threads: 0.28 ms of a 1.8 ms
  /// build, after the 0.09 ms record loop). The best bin of every axis within 1% of the best is
  /// refined to the exact plane around it, and at the root every box lies in the node, so the
  /// plane is the exact sweep's wherever it lies near such a bin: the same trees on bunny,
  /// Wuson, spd-teapot and spd-tetra (unrefined, bunny's SAH cost rose 0.16%). At least
  /// exact_below: off; below 1: 1.
  int binned_root_above = 1024;
  int threads = 0;                 ///< 0: all cores (TBB's default)
  /// Records for Woop's watertight test (TriVerts) instead of Wald's (TriAccel). The nodes and
  /// references are the same either way (the same triangles are left out as degenerate).
  bool watertight = false;
  /// Perfect splits (Wald & Havran 2006, section 4.3): a triangle that straddles a split plane
  /// is clipped to each child, so its bounds there are those of the part inside, not its box
  /// clamped to the child. Deeper trees with fewer references and a lower SAH cost: 2.1-2.3x
  /// faster tracing on long thin triangles (spd-rings), up to +40% on some other scenes, within
  /// noise on the small ones, for builds 1.0-5.3x slower (tests/bench/results/kd_clip.md).
  /// Off: clamped boxes (faster builds). The renderer turns it off for
  /// trees rebuilt as frames go by (those of meshes that move) unless told otherwise (KdClip).
  bool clip = true;
  /// View-aware SAH for the nodes of at most footprint_max_refs references: a packet of rays is
  /// traced as one, so it crosses a node when any part of its footprint does, and a node far
  /// narrower than a packet is crossed by nearly every packet that crosses its parent. The SAH
  /// then counts each length of such a node footprint_pixels pixels longer, a pixel being
  /// pixel_slope x the node's distance from footprint_eye (lengths under an eighth of a pixel
  /// grow in proportion instead). Those nodes are split only where the triangle tests saved pay
  /// for the step, and the big scenes' trees have 1.5-2.6x fewer nodes. The renderer aims it
  /// (aim_kd_build: the eye of the frame the tree is built for, and pixel_slope from its field
  /// of view and height; a tree kept for later frames, as the static meshes' tree, keeps that
  /// aim, which changes its speed, never its answers); with pixel_slope 0 (the default, no
  /// camera), footprint_pixels 0 or footprint_max_refs 0 the plain SAH builds the same tree as
  /// before, bit for bit. footprint_pixels above 1e6 counts as 1e6; an eye so far that a node's
  /// pixel overflows leaves that node to the plain SAH. The SAH cost KdBuildStats reports is
  /// always the plain SAH's.
  ///
  /// Defaults 2 pixels, 32 references (tests/bench/results/footprint_*.md, trace_experiments.md,
  /// session 36): 16-wide packets 1.13-1.14x on spd-balls, 1.03-1.08x on spd-mount-s10 and
  /// 1.05-1.06x on spd-balls-s3. Above 32 references spd-tree lost (0.88x at no limit: the
  /// SAH ignores that a packet stops at its first hits, and a merged leaf of a closed mesh is
  /// tested front and back); 4 pixels lost more there.
  float footprint_pixels = 2.0f;
  int footprint_max_refs = 32;
  float pixel_slope = 0.0f;
  glm::vec3 footprint_eye{0.0f};
  /// Vector code in the build where the CPU has it (with AVX-512: the event sweep's SAH 16
  /// events at a time, the split axis's classification and the split of a node's event lists
  /// 8 at a time, event lists under 64 sorted by rank, clipped bounds rounded outward by
  /// conversions with embedded rounding; with AVX-512 VPOPCNTDQ: the bit-mask stage's plane
  /// scan, 16 planes at a time; with AVX2 and no AVX-512: the event sweep's SAH 8 events at a
  /// time, the bit-mask stage's plane scan 8 planes at a time with popcounts by nibble lookup
  /// (also on AVX-512 without VPOPCNTDQ),
  /// event lists under 64 sorted by rank, clipped bounds rounded outward in their bits).
  /// False: the scalar code, which builds the same tree (tested); for tests and A/B runs.
  bool simd = true;
  /// The widest vector code `simd` may take: Avx512 (the default) lets the CPU decide; Avx2
  /// keeps an AVX-512 CPU on the AVX2 code that CPUs without AVX-512 run (the tests build with
  /// both and compare); Sse42 is `simd` off.
  Isa simd_limit = Isa::Avx512;
  /// With clipping, a straddling triangle's clipped polygon is kept for the children of the
  /// split, whose own splits then cut it at one plane; false: every split clips the triangle
  /// to the node's cell again (up to six planes). The same polygon up to the rounding of its
  /// cut points, and the bounds are rounded outward, so the same trees on every view tested
  /// (tested on soups); for tests and A/B runs.
  bool keep_clipped_polygons = true;
  /// With clipping, a straddler's events that its parts keep unchanged stay in place in the
  /// children's lists and only the moved ones are made anew and merged; false: all are made
  /// anew. Exactly the same trees (only the order of events at one position differs, which the
  /// build never reads; tested); for tests and A/B runs.
  bool keep_unmoved_events = true;
  /// Each inner node marks its denser child (KdNode::denser): the one whose triangles a ray
  /// crossing the node more likely meets, estimated as the chance that a ray crossing the node
  /// crosses the child (their surface areas' ratio, Cauchy-Crofton) times the chance that a ray
  /// crossing the child meets a triangle in it, 1 - exp(-A / S) at a leaf, A its triangles'
  /// area and S the cell's surface area (A / S: the chance that a line through the cell meets
  /// a closed surface of area A inside it; a lone flat triangle would count 2A / S, which
  /// marked 77 of spd-balls' 178 K inner nodes otherwise and traced as fast), combined over the
  /// children as if independent above. Shadow rays walked in the dense order
  /// (ShadowOrder::Dense) enter it first. It changes no answer. False: every bit 0 (for A/B
  /// runs).
  bool mark_denser = true;

  /// mask_below with -1 resolved. With clipping 64: larger bit-mask subtrees lose the clipping
  /// below their roots, and at 128 spd-tree's 16-wide primary rays were 0.95x (builds 0.90x,
  /// tests/bench/results/kd_mask128.md; at 256 builds 0.82x, primary rays 0.94x on spd-tree,
  /// spd-rings and spd-gears, kd_mask256.md). Without clipping 256: the masks then build the
  /// sweep's tree exactly, in 0.81-0.95x the time of 64 on the big shared scenes.
  [[nodiscard]] int effective_mask_below() const { return mask_below >= 0 ? mask_below : (clip ? 64 : 256); }
};

/// Whether the renderer's trees clip straddling triangles (KdBuildOptions::clip). Auto: on for
/// a tree built once (over the meshes that never move, which serves every frame), off for the
/// trees rebuilt as frames go by (one per moving mesh), where build time counts as much as
/// trace time. On and Off: every tree.
enum class KdClip : std::uint8_t { Auto, On, Off };

/// "auto", "on", "off" (the CLI spelling); parse_kd_clip throws rtc::Error naming the value.
[[nodiscard]] const char* kd_clip_name(KdClip clip);
[[nodiscard]] KdClip parse_kd_clip(std::string_view text);

/// What a build produced; `to_string` gives the one-line summary the tools log.
struct KdBuildStats {
  double build_ms = 0;
  std::uint64_t triangles = 0;
  std::uint64_t degenerate = 0;  ///< zero-area triangles left out of the tree
  std::uint64_t nodes = 0;
  std::uint64_t leaves = 0;
  std::uint64_t empty_leaves = 0;
  std::uint64_t prim_refs = 0;   ///< triangle references in the leaves (LeafBox slots not counted)
  std::uint64_t leaf_boxes = 0;  ///< leaves with a LeafBox
  int max_depth = 0;
  double mean_tris_per_leaf = 0;  ///< over non-empty leaves
  double sah_cost = 0;            ///< expected cost of a random ray through the root
  std::uint64_t bytes = 0;        ///< what the tree holds: nodes, references and leaf records
  /// Nodes of the exact stage whose two children were built as tasks of their own, side by side
  /// where threads were free; the tree is the same without.
  std::uint64_t forks = 0;
  /// Subtrees built by the exact stage (KdBuildOptions::exact_below, binned_root_above): 1 for
  /// a scene split by no binned node, 0 for an empty one.
  std::uint64_t blocks = 0;
  [[nodiscard]] std::string to_string() const;
};

/// An immutable kd-tree. Triangle ids (what hits report, and what ties are broken by) are the
/// indices into the arrays given to build(), or the `ids` given with them. Thread-safe for
/// concurrent queries after construction.
class KdTree {
 public:
  KdTree() = default;

  /// Builds over triangles (indices into positions). O(N log N): events sorted once per axis,
  /// then each node's sorted lists are split in linear time. Parallel over subtrees with TBB.
  /// The tree is a pure function of the input and options (not of the thread count).
  /// `ids`: empty, or one id per triangle, below 2^31 - 1 (hits carry them as int32, -1 for a
  /// miss): a tree over some of a scene's triangles then reports the scene's triangle ids, so
  /// that several trees traced in turn break ties as one tree over all of them would. Positions
  /// that no triangle references are not read.
  static KdTree build(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                      const KdBuildOptions& options = {}, std::span<const std::uint32_t> ids = {});

  [[nodiscard]] std::span<const KdNode> nodes() const { return nodes_.span(); }
  /// Leaf references: the triangles' indices in the arrays given to build() (not their ids
  /// when built with ids; TriAccel::id gives those), leaf after leaf. A leaf with a LeafBox
  /// (KdNode::has_box()) has one more slot before its first (at KdNode::prim_offset() - 1),
  /// kLeafBoxRef, whose record is that box.
  [[nodiscard]] std::span<const std::uint32_t> prim_refs() const { return prim_refs_.span(); }
  /// The 48-byte record of each leaf reference, in leaf order: leaf_records()[i] is the record
  /// of triangles[prim_refs()[i]] (make_tri_accel, or make_tri_verts when watertight(), with
  /// its id), or the leaf's LeafBox where prim_refs()[i] is kLeafBoxRef, so a leaf's box and
  /// triangles are read in sequence with no indirection. The traversal
  /// reads only these. (No record per triangle is kept: on spd-tree that was 44 MB beside these
  /// 104 MB, read by nothing but tests.)
  [[nodiscard]] std::span<const TriRecord> leaf_records() const { return leaf_records_.span(); }
  /// Whether the records are Woop's watertight ones (KdBuildOptions::watertight).
  [[nodiscard]] bool watertight() const { return watertight_; }
  /// Scene bounds, slightly enlarged so rays that graze the outermost triangles still enter.
  [[nodiscard]] const Aabb& bounds() const { return bounds_; }
  [[nodiscard]] const KdBuildStats& stats() const { return stats_; }
  [[nodiscard]] bool empty() const { return nodes_.size() == 0; }

 private:
  RawArray<KdNode> nodes_;  // these three written once each by the build, in parallel
  RawArray<std::uint32_t> prim_refs_;
  RawArray<TriRecord> leaf_records_;
  Aabb bounds_;
  KdBuildStats stats_;
  bool watertight_ = false;
};

/// The 48-byte record for triangle (a, b, c); k = 3 when the triangle has zero area.
[[nodiscard]] TriAccel make_tri_accel(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);
/// make_tri_accel for triangles [first, first + count) of `triangles` (indices into
/// `positions`, in range), written to out[0, count).wald: the same bits, eight triangles at a
/// time in double where `isa` is AVX-512 and the CPU has it (the scalar code otherwise). The
/// kd-tree build's records.
void make_tri_accels(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles, std::size_t first,
                     std::size_t count, TriRecord* out, Isa isa);
/// The watertight record for triangle (a, b, c); k = 3 exactly when make_tri_accel gives 3.
[[nodiscard]] TriVerts make_tri_verts(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);

}  // namespace rtc
