// Matrix trees (Andrysco & Tricoche 2010/2011): every level of a regular tree is one
// block-sparse matrix, so parent, child and neighbour positions are computed, not stored.
//
// Level l has 2^logDims[l][a] nodes along axis a over the root box. Going down one level splits
// every node at its centre along a set of axes:
//   Octree     every axis whose node extent is more than half the largest (a cube root splits
//              all three: the classic octree; a flat or long scene is not split along its thin
//              axes until the nodes are about cubic, so no level is wasted on empty slabs);
//   RegularKd  the single axis of largest node extent (ties: x, then y, then z) — for a cubic
//              root this is the paper's x, y, z alternation.
// A node exists iff some primitive overlaps it. All primitives are referenced at the bottom
// level (height H); upper levels only record existence (1 byte per node). Existence is monotone
// along any root-to-leaf path, which is what makes the O(log H) leaf search a binary search.
//
// The ray walk probes existence at every step, so the tree keeps two derived copies of it that
// fit in cache (buildWalkCaches(), after every build): one bit per entry of each 8x8x8 leaf
// block, and dense bits for the small upper levels. They answer the same questions as the
// block-sparse levels, bit for bit (test_matrix_tree WalkCachesMirrorTheLevels). Where every
// level's nodes either lie inside one leaf block or are unions of whole blocks (octrees with
// 8x8x8 leaf blocks), a third copy, a byte per leaf-level pointer-matrix cell, gives the level
// of the largest empty node around each absent block: nodeOf() then classifies any bottom-level
// cell from one pointer read and its block's mask words, where locate() binary searches the
// levels, so a ray steps across empty space without a search per step. On scenes with many
// empty cells inside the allocated leaf blocks (surfaces), a fourth copy, the step table, holds
// nodeOf()'s answer itself, one byte per bottom-level cell of every allocated block: the walk
// then reads one byte per step, whatever the node it steps through (buildStepTable()).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "mtree/core/block_sparse.h"
#include "mtree/core/geometry.h"
#include "mtree/core/layout.h"

namespace mtree {

enum class TreeKind : int { Octree = 0, RegularKd = 1 };
enum class OverlapMode : int { Exact = 0, BoundingBox = 1 };
/// How the builder groups the (leaf, primitive) references by leaf (see builder.h). Both give
/// the same tree, bit for bit, for any thread count.
///   Radix     the paper's §5.1: (leaf, primitive) pairs at per-primitive scanned offsets, a
///             stable radix sort by leaf, leaf ranges from neighbouring keys.
///   Counting  after the blocks are allocated the leaf storage is known and dense: count the
///             references per leaf, scan over the leaves, scatter the primitive ids with per-leaf
///             cursors, sort each leaf's few ids (the scatter's order depends on the threads).
///             No pair keys, no sort passes over all references.
enum class BuildSort : int { Radix = 0, Counting = 1 };

const char* treeKindName(TreeKind k);

struct BuildOptions {
  TreeKind kind = TreeKind::Octree;
  /// Levels below the root; 0 = chosen from the scene (see chooseHeight()).
  int height = 0;
  /// Block edge B of every level's block-sparse matrix (power of two, 1..32).
  int blockEdge = 8;
  /// Exact: separating-axis test per candidate leaf; BoundingBox: every leaf the primitive's box
  /// touches (faster build, more references, more primitive tests per ray).
  OverlapMode overlap = OverlapMode::Exact;
  /// Automatic height: the leaf extent targeted is leafScale x the median primitive extent...
  double leafScale = 2.0;
  /// ...then one level up at a time while the primitives' bounding boxes cover more than this
  /// many candidate leaves on average (sampled): caps build cost and memory for scenes whose
  /// median hides many large primitives. About 0.4-0.7 of the candidates become references.
  double maxCandidates = 8.0;
  /// OpenMP threads; 0 = OpenMP's default.
  int threads = 0;
  /// Grouping of the references by leaf (same tree either way). The OpenCL builder always
  /// uses the radix sort.
  BuildSort sort = BuildSort::Radix;
};

struct BuildStats {
  std::vector<std::pair<std::string, double>> phasesMs;  // in build order
  double totalMs = 0;
  uint64_t references = 0;    // (leaf, primitive) pairs
  uint64_t leaves = 0;        // existing leaves
  uint64_t primitives = 0;
  int height = 0;
  bool autoHeight = false;
  double medianPrimitiveExtent = 0;
};

struct TraversalStats {
  uint64_t nodeVisits = 0;  // node lookups (each is two memory reads)
  uint64_t primTests = 0;   // primitive intersection tests
  uint64_t cells = 0;       // leaves and empty nodes stepped through
  void add(const TraversalStats& o) {
    nodeVisits += o.nodeVisits;
    primTests += o.primTests;
    cells += o.cells;
  }
};

/// A node of the tree: its level and integer coordinates in that level's matrix.
/// level < 0: outside the tree (point outside the root box, or empty tree).
struct NodeRef {
  int level = -1;
  int c[3] = {0, 0, 0};
  bool exists = false;  // true only for an existing bottom-level node (a leaf with primitives)
  MtLeafRange range{MT_NULL, MT_NULL};  // the leaf's primitives when exists (read once, kept)
};

class MatrixTree {
 public:
  MatrixTree() = default;

  // ---- shape ----
  TreeKind kind() const { return kind_; }
  int height() const { return height_; }
  int numLevels() const { return height_ + 1; }
  bool empty() const { return empty_; }
  const Box& rootBox() const { return root_; }
  Vec3 cellSize(int level) const { return cellSize_[level]; }
  /// 1 / the bottom level's cell size per axis, as leafCoords() and the ray walk use it.
  Vec3 inverseLeafSize() const { return invLeaf_; }
  int logDim(int level, int axis) const { return logDims_[level][axis]; }
  int dim(int level, int axis) const { return 1 << logDims_[level][axis]; }
  int blockEdge() const { return blockEdge_; }

  // ---- storage ----
  const BlockSparseMatrix<uint8_t>& innerLevel(int l) const { return inner_[l]; }
  const BlockSparseMatrix<MtLeafRange>& leafLevel() const { return leaves_; }
  const LargeVector<uint32_t>& primitiveIndices() const { return prims_; }
  /// Bytes of level l (pointer matrix + allocated blocks); bytes() adds the walk's caches.
  size_t levelBytes(int l) const { return l == height_ ? leaves_.bytes() : inner_[l].bytes(); }
  /// The leaf level's occupancy masks: one bit per entry of every allocated 8x8x8 leaf block,
  /// 8 words per block (word k = the block's z-slice k, bit 8y + x), set where a leaf exists.
  /// A copy of `range.begin != MT_NULL` that is 64x smaller, so the ray walk tests an empty
  /// bottom-level cell, and whether its parent exists, in cache instead of loading leaf ranges.
  /// Empty (and unused) when the leaf blocks are not 8x8x8.
  const std::vector<uint64_t>& leafMasks() const { return leafMask_; }
  /// Dense existence bits of the upper levels, one bit per node, for each level l < H whose
  /// dense bit array is no larger than its block-sparse storage (so they at most double the
  /// inner levels' bytes, which are a small part of the tree): a probe during the walk is one
  /// word read from a small array that stays in cache. Levels below use the block-sparse bytes.
  int denseLevels() const { return denseLevels_; }
  size_t walkCacheBytes() const {
    return (leafMask_.size() + levelBits_.size() + stepBox_.size()) * sizeof(uint64_t) + blockEmpty_.size() +
           stepLevel_.size() + stepBlock_.size() * sizeof(uint32_t);
  }
  /// Whether traverseRay() steps by the step table (see buildStepTable()): built with the other
  /// walk caches where nodeOf() is available and at least half the bottom-level cells of the
  /// allocated leaf blocks are empty, so that its 512 bytes per block buy steps through empty
  /// space: surfaces (80-83% of those cells empty on the meshes in ../shared/data), not volume
  /// meshes (0-21%), whose walk is mostly leaves that the masks answer in one probe.
  bool hasStepTable() const { return !stepBlock_.empty(); }
  /// Whether traverseRay() may walk by the step table (on by default; kept across builds). Off,
  /// it walks as a tree without one does: for comparing the two walks on one tree.
  void enableStepTable(bool on) { stepTableOn_ = on; }
  /// The step table's node for bottom-level cell L (in range; hasStepTable()): its level, and
  /// in `leaf` whether it is an existing leaf. nodeOf()'s answer (test_matrix_tree checks every
  /// cell); the walk reads the table inline.
  int stepTableLevel(const int L[3], bool& leaf) const {
    const uint8_t v = stepLevel_[stepBlock_[leaves_.pointerIndex(L[0], L[1], L[2])] + leaves_.localIndex(L[0], L[1], L[2])];
    leaf = (v & kStepLeaf) != 0;
    return v & ~kStepLeaf;
  }
  /// Whether nodeOf() is available (the walk caches hold the per-block empty levels).
  bool fastNodeOf() const { return !blockEmpty_.empty(); }
  /// locate(L, 0, H + 1)'s answer (the leaf at bottom-level cell L, or the largest empty node
  /// containing L) from the walk caches: one pointer read and the block's occupancy masks, a
  /// byte of blockEmpty_ where the block is absent. Only where fastNodeOf(); L in range.
  /// Counted as one node visit for a leaf, two for an empty cell (the masks' probes of L's
  /// ancestors read one cache line, the block's, and count as one).
  NodeRef nodeOf(const int L[3], TraversalStats* st) const;
  /// Does inner node c of level l < H exist? The dense bits where they are kept, else one
  /// block-sparse access.
  bool innerExists(int level, const int c[3]) const {
    if (level < denseLevels_) {
      const uint64_t i = denseBit(level, c);
      return (levelBits_[i >> 6] >> (i & 63)) & 1u;
    }
    const uint8_t* v = inner_[level].find(c[0], c[1], c[2]);
    return v && *v;
  }
  /// Recomputes the walk's caches (leaf occupancy masks, dense upper-level bits) from the
  /// levels. The builders call it; anything that fills the levels by other means must too.
  void buildWalkCaches(int threads);
  uint32_t levelBlocks(int l) const { return l == height_ ? leaves_.numBlocks() : inner_[l].numBlocks(); }
  /// Total bytes of the tree: all levels plus the primitive index array.
  size_t bytes() const;
  /// Bytes of the work arrays the last build kept for the next one (not in bytes()).
  size_t buildScratchBytes() const {
    const BuildScratch& s = scratch_;
    return (s.counts.capacity() + s.offsets.capacity() + s.keys.capacity() + s.values.capacity() +
            s.tmpKeys.capacity() + s.tmpValues.capacity()) * sizeof(uint32_t) +
           s.masks.capacity() * sizeof(uint64_t) + s.marks.capacity();
  }
  /// Frees those work arrays (the next build allocates them again).
  void releaseBuildScratch() { scratch_ = BuildScratch{}; }
  uint64_t numLeaves() const;

  // ---- queries (all const and thread-safe) ----
  /// Does node c of level l exist? One block-sparse access.
  bool nodeExists(int level, const int c[3]) const {
    if (level == height_) {
      const MtLeafRange* r = leaves_.find(c[0], c[1], c[2]);
      return r && r->begin != MT_NULL;
    }
    const uint8_t* v = inner_[level].find(c[0], c[1], c[2]);
    return v && *v;
  }
  /// Bottom-level coordinates of the leaf cell containing p; false if p is outside the root box.
  /// Inside it (p >= lo: p - lo >= 0) truncation is floor, so no libm floor call per axis.
  bool leafCoords(Vec3 p, int L[3]) const;
  /// The ancestor at `level` of bottom-level cell L.
  void ancestor(const int L[3], int level, int c[3]) const {
    for (int a = 0; a < 3; ++a) c[a] = L[a] >> (logDims_[height_][a] - logDims_[level][a]);
  }
  /// Sub-linear leaf finding: hash into the bottom level; if that leaf is absent, binary search
  /// the root-to-leaf path for the deepest existing node. Returns the leaf, or the largest empty
  /// node containing p (level = deepest existing + 1, exists = false).
  NodeRef leafFind(Vec3 p, TraversalStats* st = nullptr) const;
  /// Same answer by a plain top-down descent, O(H): the reference for tests.
  NodeRef leafFindTopDown(Vec3 p) const;
  /// The leaf holding p if it exists (leafFind's answer then), else exists = false without the
  /// search for the deepest existing node: one block-sparse access (with the walk caches, the
  /// pointer and the block's mask word first), for point location, which only needs the leaf
  /// (a point in no leaf is in no primitive).
  NodeRef leafHolding(Vec3 p) const {
    NodeRef r;
    int L[3];
    if (!leafCoords(p, L)) return r;
    // The masks first, as the walk's bottomCell(): a point in an empty cell (most of a
    // surface's box) is answered from the pointer matrix and the 64-byte mask words, which stay
    // in cache, without reading the cell's 8-byte leaf range.
    bool leaf;
    if (leafMask_.empty()) {
      leaf = leafAt(L, r.range);
    } else {
      maskedLeaf(L, r.range, leaf);
    }
    if (!leaf) return r;
    r.level = height_;
    for (int a = 0; a < 3; ++a) r.c[a] = L[a];
    r.exists = true;
    return r;
  }
  /// Leaf finding from bottom-level coordinates with the search bracketed: level `lo` is known to
  /// exist on the path and level `hi` known absent (hi = H+1 if unknown).
  NodeRef locate(const int L[3], int lo, int hi, TraversalStats* st) const;
  /// Neighbour finding (paper §2.4): the leaf or largest empty node across face (axis, dir) of
  /// `n` that contains bottom-level cell L (which must lie just across that face). The node of
  /// n's size across the face brackets the binary search. level < 0 if that face is the root's.
  NodeRef neighbourFind(const NodeRef& n, int axis, int dir, const int L[3], TraversalStats* st) const;
  /// The leaf-finding answer for bottom-level cell L when its ancestor at level `hi` is known
  /// absent: the empty child of L's deepest existing ancestor above `hi`.
  NodeRef searchAbove(const int L[3], int hi, TraversalStats* st) const;
  /// Box of node c at level l, in world coordinates. Inline: the builder calls it per reference.
  Box nodeBox(int level, const int c[3]) const {
    Box b;
    const Vec3 cs = cellSize_[level];
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = root_.lo[a] + c[a] * cs[a];
      b.hi[a] = root_.lo[a] + (c[a] + 1) * cs[a];
    }
    return b;
  }
  /// Primitive range of an existing leaf.
  MtLeafRange leafRange(const NodeRef& n) const { return leaves_.get(n.c[0], n.c[1], n.c[2]); }
  /// The leaf at bottom-level cell L if it exists (its range in r), one block-sparse access.
  bool leafAt(const int L[3], MtLeafRange& r) const {
    const MtLeafRange* p = leaves_.find(L[0], L[1], L[2]);
    if (!p || p->begin == MT_NULL) return false;
    r = *p;
    return true;
  }

  /// Walks the ray o + t d, t in [tmin, tmax], front to back through the leaves and empty nodes
  /// it crosses, stepping from node to neighbour (no stack, no restart). For every existing leaf
  /// calls fn(const uint32_t* prims, uint32_t count, double tEnter, double tExit) -> bool, or,
  /// where fn takes a fifth argument, fn(..., const int* L) with the leaf's bottom-level
  /// coordinates; a true return stops the walk. The walk is robust to rays parallel to planes,
  /// rays starting inside, and rays along node faces: the exit axis advances by an integer step,
  /// the other coordinates are clamped into the current node, so it never skips or revisits a
  /// node.
  /// With the step table (hasStepTable(), enabled) the nodes come from the table (TableWalk), with
  /// the same arithmetic as the walk that classifies each cell from the masks and the levels, so
  /// fn sees the same calls with the same arguments either way (test_matrix_tree
  /// StepTableWalkIsTheTreeWalk). Stats are a compile-time policy of the same walk: with `st` the
  /// table walk counts one node visit (its byte) and one cell per step, without it the counters
  /// are compiled out; the walk without the table counts its probes as the paper does.
  template <class LeafFn>
  void traverseRay(Vec3 o, Vec3 d, double tmin, double tmax, LeafFn&& fn, TraversalStats* st) const;

  /// The walk by the step table one step at a time, for traverseRay() and for walks that keep
  /// several rays in flight (rays/batch_trace.h): see TableWalk below.
  class TableWalk;

 private:
  template <class Prims>
  friend class MatrixTreeBuilder;

  TreeKind kind_ = TreeKind::Octree;
  int height_ = 0;
  int blockEdge_ = 8;
  bool empty_ = true;
  Box root_;
  Vec3 invLeaf_;  // 1 / bottom-level cell size
  std::vector<std::array<int, 3>> logDims_;
  std::vector<Vec3> cellSize_;
  std::vector<BlockSparseMatrix<uint8_t>> inner_;  // levels 0..H-1
  BlockSparseMatrix<MtLeafRange> leaves_;          // level H
  LargeVector<uint32_t> prims_;
  std::vector<uint64_t> leafMask_;  // see leafMasks()
  std::vector<uint64_t> levelBits_;  // see innerExists()
  // nodeOf(): per leaf-level pointer-matrix cell whose block is absent, the level of the largest
  // empty node containing the block (0xFF where the block exists); and for k = 1 ...
  // blockLevels_, the bits of L's ancestor at level H - k within its block's mask words (for L at
  // (0, 0, 0) of the block; shifted by the low coordinates L keeps), the AND-masks that clear
  // the coordinate bits below that ancestor, and the number of z-slices (mask words) it spans.
  // Level H - blockLevels_ is the block itself.
  std::vector<uint8_t> blockEmpty_;
  struct BlockGroup {
    uint64_t bits = 0;
    int low[3] = {0, 0, 0};
    int depth = 0;
  };
  std::array<BlockGroup, 10> group_{};
  int blockLevels_ = 0;
  /// Fills blockEmpty_ and group_ after the leaf masks (leaves them empty where not applicable).
  void buildBlockEmpty();
  /// The level of the largest empty node containing the empty bottom-level cell at (x, y, z)
  /// (0..7) of an allocated block with mask words w: the child on its path of the first
  /// ancestor, from level H - k0 up to the block, with a leaf under it; -1 if the block has no
  /// leaf at all.
  int emptyLevelInBlock(int x, int y, int z, const uint64_t* w, int k0) const {
    for (int k = k0; k <= blockLevels_; ++k) {
      const BlockGroup& g = group_[k];
      const uint64_t bits = g.bits << ((x & g.low[0]) + 8 * (y & g.low[1]));
      const int z0 = z & g.low[2];
      uint64_t any = 0;
      for (int q = 0; q < g.depth; ++q) any |= w[z0 + q];
      if (any & bits) return height_ - k + 1;
    }
    return -1;
  }
  // The step table (buildStepTable()): for every allocated leaf block b, 512 bytes at b * 512 (the
  // offset of its leaf ranges in leaves_.data()), in the block's local order; then one block of
  // 512 equal bytes per level l <= H, at (numBlocks + l) * 512, for the cells of absent blocks.
  // A byte is kStepLeaf | H for a leaf, else the level of the largest empty node containing the
  // cell (H: an empty cell whose parent exists). stepBlock_ has the offset of every leaf
  // pointer-matrix cell's 512 bytes: its block's, or the block of its blockEmpty_ level.
  static constexpr uint8_t kStepLeaf = 0x80;
  std::vector<uint8_t> stepLevel_;
  std::vector<uint32_t> stepBlock_;
  // Empty boxes (TableWalk): per leaf pointer-matrix cell whose block is absent, a box of absent
  // blocks containing it, in block units: bytes 0-2 its low corner (x, y, z), bytes 4-6 its high
  // corner (inclusive); the cell itself where the block exists. Grown from the largest empty node
  // containing the block (buildStepBoxes()), so never smaller than that node.
  std::vector<uint64_t> stepBox_;
  /// Fills stepBox_ (buildStepTable() calls it).
  void buildStepBoxes();
  // Per level, the bottom-level cells per node along each axis as a shift (logDims[H] -
  // logDims[l]), and ~(2^shift - 1): a bottom-level coordinate ANDed with it is the first
  // bottom-level cell of its node at that level (TableWalk::step).
  std::array<std::array<int, 3>, MT_MAX_LEVELS> stepShift_{};
  std::array<std::array<int, 4>, MT_MAX_LEVELS> stepMask_{};
  int stepLogPtr_[2] = {0, 0};  // log2 of the leaf pointer matrix's cells along x and y
  bool stepTableOn_ = true;
  /// Fills the step table after buildBlockEmpty() (leaves it empty where nodeOf() is not
  /// available or the blocks are mostly leaves).
  void buildStepTable(int threads);
  /// nodeOf() below an empty bottom-level cell L of an allocated block with mask words w: the
  /// first ancestor, from level H - k0 up, with a leaf under it; its child on L's path.
  NodeRef emptyInBlock(const int L[3], const uint64_t* w, int k0, TraversalStats* st) const;
  struct DenseLevel {
    size_t offset = 0;  // first word of the level in levelBits_
    int lx = 0, ly = 0;  // log2 of the level's node counts along x and y
  };
  std::array<DenseLevel, MT_MAX_LEVELS> dense_{};
  int denseLevels_ = 0;
  /// Bit index of node c of dense level l in levelBits_ (x fastest, then y, then z).
  uint64_t denseBit(int level, const int c[3]) const {
    const DenseLevel& d = dense_[level];
    return 64 * uint64_t(d.offset) +
           ((((uint64_t(c[2]) << d.ly) | uint64_t(c[1])) << d.lx) | uint64_t(c[0]));
  }
  // Bottom-level sibling test (walk): the bits of a leaf's parent's children within one mask
  // word, for a leaf at (x, y) = (0, 0) of its block, and whether the parent also spans z.
  uint64_t siblingBits_ = 1;
  int siblingLow_[3] = {~0, ~0, ~0};  // AND-mask clearing the split axes' low coordinate bit
  bool siblingZ_ = false;

  /// The bottom-level cell L (in range) through the occupancy masks (leafMask_ not empty):
  /// `leaf` whether it is a leaf (then its range in r); returns its block's mask words, null
  /// where the block is absent.
  const uint64_t* maskedLeaf(const int L[3], MtLeafRange& r, bool& leaf) const {
    leaf = false;
    const uint32_t b = leaves_.pointers()[leaves_.pointerIndex(L[0], L[1], L[2])];
    if (b == MT_NULL) return nullptr;
    const uint64_t* w = leafMask_.data() + size_t(b) * 8;
    const uint32_t local = leaves_.localIndex(L[0], L[1], L[2]);  // 64 z + 8 y + x: word z, bit 8 y + x
    leaf = (w[local >> 6] >> (local & 63)) & 1u;
    if (leaf) r = leaves_.data()[size_t(b) * 512 + local];
    return w;
  }
  /// The bottom-level cell L (in range) through the occupancy masks: 1 = a leaf (its range in
  /// r), 0 = an empty cell whose parent exists, -1 = the parent is absent too. Two node visits
  /// at most (the cell, its parent), as leafAt + an existence probe would count them.
  int bottomCell(const int L[3], MtLeafRange& r, TraversalStats* st) const;
  // Work arrays of the build, kept between builds so that rebuilding every frame does not pay
  // for allocating and first-touching them again (the paper's §6 remark on memory handling).
  struct BuildScratch {
    LargeVector<uint32_t> counts, offsets, keys, values, tmpKeys, tmpValues;
    LargeVector<uint64_t> masks;
    LargeVector<uint8_t> marks;
  };
  BuildScratch scratch_;
};

/// floor(x) clamped to [lo, hi] for 0 <= lo <= hi, clamping in floating point first so a huge x
/// cannot overflow: below lo (and NaN) gives lo, and from lo up truncation is floor, so no libm
/// call (std::floor is one without SSE4.1, which a portable build does not assume). Every cell
/// index of the trees has lo = 0.
inline int cellIndexNonNegative(double x, int lo, int hi) {
  if (!(x >= lo)) return lo;  // also catches NaN
  if (x >= hi) return hi;
  return static_cast<int>(x);
}

inline bool MatrixTree::leafCoords(Vec3 p, int L[3]) const {
  if (empty_ || !isFinite(p) || !root_.contains(p)) return false;
  const std::array<int, 3>& ld = logDims_[height_];
  for (int a = 0; a < 3; ++a) L[a] = cellIndexNonNegative((p[a] - root_.lo[a]) * invLeaf_[a], 0, (1 << ld[a]) - 1);
  return true;
}

/// Computes the per-level logDims of a tree of `kind` over a root box of extent `e`, `height` levels
/// below the root.
std::vector<std::array<int, 3>> levelShapes(TreeKind kind, Vec3 e, int height);

/// The automatic height rule: the shallowest level whose largest node extent is at most
/// leafScale x medianExtent, capped so that the leaf level's pointer matrix (for blocks of
/// edge blockEdge) has at most 2^24 cells and no axis more than 2^30 nodes.
int chooseHeight(TreeKind kind, Vec3 rootExtent, double medianExtent, double leafScale, int blockEdge);

// ---------------------------------------------------------------------------------------------
// Leaf and neighbour finding: inline, they run once per step of every ray.
inline NodeRef MatrixTree::locate(const int L[3], int lo, int hi, TraversalStats* st) const {
  NodeRef r;
  const int H = height_;
  if (hi > H) {
    if (st) ++st->nodeVisits;
    if (leafAt(L, r.range)) {
      r.level = H;
      for (int a = 0; a < 3; ++a) r.c[a] = L[a];
      r.exists = true;
      return r;
    }
    hi = H;
  }
  // Invariant: the ancestor at `lo` exists, the ancestor at `hi` does not.
  int c[3];
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    ancestor(L, mid, c);
    if (st) ++st->nodeVisits;
    if (innerExists(mid, c)) lo = mid;
    else hi = mid;
  }
  r.level = hi;
  ancestor(L, hi, r.c);
  r.exists = false;
  return r;
}

inline NodeRef MatrixTree::neighbourFind(const NodeRef& n, int axis, int dir, const int L[3],
                                  TraversalStats* st) const {
  int c[3] = {n.c[0], n.c[1], n.c[2]};
  c[axis] += dir;
  if (c[axis] < 0 || c[axis] >= dim(n.level, axis)) return NodeRef{};
  // The same-size node across the face brackets the search: if it exists, the answer is at or
  // below its level; if not, above it.
  if (st) ++st->nodeVisits;
  if (n.level == height_) {
    NodeRef r;
    if (leafAt(L, r.range)) {  // L is that same-size node: the next leaf, one access
      r.level = height_;
      for (int a = 0; a < 3; ++a) r.c[a] = L[a];
      r.exists = true;
      return r;
    }
  } else if (innerExists(n.level, c)) {
    return locate(L, n.level, height_ + 1, st);
  }
  return searchAbove(L, n.level, st);
}

inline NodeRef MatrixTree::searchAbove(const int L[3], int hi, TraversalStats* st) const {
  // The answer is the empty child of the deepest existing ancestor of L above level hi.
  // Search up from the bracket with doubling steps (a gallop, then a binary search inside the
  // last step): the common case, a neighbour under the same parent, costs one access instead of
  // log2(level), and the worst case stays O(log h).
  int step = 1;
  int lo = 0;
  int a[3];
  while (hi - step > 0) {
    const int probe = hi - step;
    ancestor(L, probe, a);
    if (st) ++st->nodeVisits;
    if (innerExists(probe, a)) {
      lo = probe;
      break;
    }
    hi = probe;
    step *= 2;
  }
  return locate(L, lo, hi, st);
}

inline NodeRef MatrixTree::emptyInBlock(const int L[3], const uint64_t* w, int k0, TraversalStats* st) const {
  // One node visit for all the probes: they read the block's mask words, one cache line.
  if (st) ++st->nodeVisits;
  const int level = emptyLevelInBlock(L[0] & 7, L[1] & 7, L[2] & 7, w, k0);
  if (level >= 0) {
    // The ancestor above `level` holds a leaf, so it exists; its child on L's path does not.
    NodeRef r;
    r.level = level;
    ancestor(L, r.level, r.c);
    return r;
  }
  // A block without leaves (not built by the builders): its node is absent, search above it.
  return searchAbove(L, height_ - blockLevels_, st);
}

inline NodeRef MatrixTree::nodeOf(const int L[3], TraversalStats* st) const {
  const size_t p = leaves_.pointerIndex(L[0], L[1], L[2]);
  const uint32_t b = leaves_.pointers()[p];
  if (st) ++st->nodeVisits;  // the pointer and the cell's bit: as one leaf access
  if (b == MT_NULL) {
    if (st) ++st->nodeVisits;  // the block's empty level
    NodeRef r;
    r.level = blockEmpty_[p];
    ancestor(L, r.level, r.c);
    return r;
  }
  const uint64_t* w = leafMask_.data() + size_t(b) * 8;
  const uint32_t local = leaves_.localIndex(L[0], L[1], L[2]);
  if ((w[local >> 6] >> (local & 63)) & 1u) {
    NodeRef r;
    r.range = leaves_.data()[size_t(b) * 512 + local];
    r.level = height_;
    for (int a = 0; a < 3; ++a) r.c[a] = L[a];
    r.exists = true;
    return r;
  }
  return emptyInBlock(L, w, 1, st);
}

MT_ALWAYS_INLINE int MatrixTree::bottomCell(const int L[3], MtLeafRange& r, TraversalStats* st) const {
  const int H = height_;
  if (st) ++st->nodeVisits;
  if (leafMask_.empty()) {  // leaf blocks not 8x8x8: the block-sparse accesses themselves
    if (leafAt(L, r)) return 1;
    if (H == 0) return -1;
    int c[3];
    ancestor(L, H - 1, c);
    if (st) ++st->nodeVisits;
    return innerExists(H - 1, c) ? 0 : -1;
  }
  bool leaf;
  const uint64_t* w = maskedLeaf(L, r, leaf);
  if (!w) return -1;  // no leaf in this 8x8x8 block, so none under the cell's parent
  if (leaf) return 1;
  const int x = L[0] & 7, y = L[1] & 7, z = L[2] & 7;
  if (st) ++st->nodeVisits;
  const int zs = z & siblingLow_[2];
  const uint64_t any = w[zs] | (siblingZ_ ? w[zs + 1] : 0);
  return (any & (siblingBits_ << (8 * (y & siblingLow_[1]) + (x & siblingLow_[0])))) ? 0 : -1;
}

// ---------------------------------------------------------------------------------------------
namespace detail {
/// A ray's set-up for the walks: per axis the reciprocal direction (no division per step; 0 on an
/// axis the ray does not move along: d = 0, or a reciprocal that is not finite), +inf in `never`
/// on such an axis (so every axis has an exit plane), which face it leaves by, and [t0, t1], the
/// interval clipped to the root box by a slab test without branches on the slab order (many rays
/// of a frame miss the root box, and this is all they cost). False: nothing to walk.
struct RayClip {
  double inv[3], never[3];
  bool up[3];
  double t0, t1;
  MT_ALWAYS_INLINE bool clip(const Box& root, Vec3 o, Vec3 d, double tmin, double tmax) {
    if (!isFinite(o) || !isFinite(d) || !(tmin <= tmax)) return false;
    if (d.x == 0 && d.y == 0 && d.z == 0) return false;
    bool moves[3];
    for (int a = 0; a < 3; ++a) {
      inv[a] = d[a] != 0 ? 1.0 / d[a] : 0.0;
      moves[a] = std::fabs(inv[a]) < std::numeric_limits<double>::infinity() && d[a] != 0;
      if (!moves[a]) inv[a] = 0.0;
      up[a] = d[a] > 0;
      never[a] = moves[a] ? 0.0 : std::numeric_limits<double>::infinity();
    }
    t0 = tmin;
    t1 = tmax;
    for (int a = 0; a < 3; ++a) {
      if (!moves[a]) {
        if (o[a] < root.lo[a] || o[a] > root.hi[a]) return false;
        continue;
      }
      const double tn = (root.lo[a] - o[a]) * inv[a], tf = (root.hi[a] - o[a]) * inv[a];
      t0 = std::max(t0, std::min(tn, tf));
      t1 = std::min(t1, std::max(tn, tf));
    }
    return t0 <= t1;
  }
};
/// cellIndexNonNegative(x, lo, hi) without branches: the same value for every x, NaN included
/// (below lo or NaN: lo; from hi up: hi; else truncation, which is floor there).
MT_ALWAYS_INLINE int clampCell(double x, int lo, int hi) {
  double c = x >= lo ? x : double(lo);
  c = c >= hi ? double(hi) : c;
  return static_cast<int>(c);
}
/// The nearest of three exit planes (ties: the lower axis), or -1 if the ray interval ends first
/// (tExit = t1). Written without branches on the comparisons, which a step cannot predict.
MT_ALWAYS_INLINE int nearestExit(double tx, double ty, double tz, double t1, double& tExit) {
  int ax = ty < tx ? 1 : 0;
  double tm = ty < tx ? ty : tx;
  ax = tz < tm ? 2 : ax;
  tm = tz < tm ? tz : tm;
  const bool ends = !(tm < t1);
  tExit = ends ? t1 : tm;
  return ends ? -1 : ax;
}
/// The ray walk's t of the plane at integer cell coordinate `edge` (cells of extent cs) for a
/// ray whose origin is at o from the root's corner, with reciprocal direction inv; `never` is
/// +inf on an axis the ray does not move along (inv = 0 there), else 0. One expression for both
/// walks, so they step alike to the bit.
MT_ALWAYS_INLINE double planeCrossing(int edge, double cs, double o, double inv, double never) {
  return (edge * cs - o) * inv + never;
}
/// traverseRay's leaf call: fn(ids, count, tEnter, tExit), or fn(ids, count, tEnter, tExit, L)
/// where fn takes the leaf's bottom-level coordinates too.
template <class LeafFn>
MT_ALWAYS_INLINE bool callLeaf(LeafFn& fn, const uint32_t* ids, uint32_t count, double tEnter, double tExit,
                               int x, int y, int z) {
  if constexpr (std::is_invocable_v<LeafFn&, const uint32_t*, uint32_t, double, double, const int*>) {
    const int L[3] = {x, y, z};
    return fn(ids, count, tEnter, tExit, static_cast<const int*>(L));
  } else {
    return fn(ids, count, tEnter, tExit);
  }
}
}  // namespace detail

/// One ray's place in the walk by the step table (MatrixTree::TableWalk): its constants, in the
/// root box's frame (origin at the root's lo corner), and the cell it is in.
struct TableRay {
  double o[3], d[3], inv[3], never[3];
  bool up[3];
  double t1;     // end of the ray's interval, clipped to the root box
  double te;     // where the ray enters the current cell
  int L[3];      // the current bottom-level cell
  uint32_t e;    // its entry in the step table
  uint32_t p;    // its leaf pointer-matrix cell (its block's)
  int stepsLeft; // the walk's bound on steps (3 x the cells along the axes + 8): never reached by
                 // a walk that advances, which every walk does
};

/// What one step found: the node the ray was in (a leaf when `leaf`: its step-table entry `here`
/// is its index in the leaf level's storage), the ray's interval in it, the node's bottom-level
/// cell the ray was in, and whether the ray goes on to a next node (already in the TableRay).
struct TableStep {
  uint32_t here;
  bool leaf, next;
  double tEnter, tExit;
  int L[3];
};

/// The walk by the step table (buildStepTable()): one step reads the byte of the ray's
/// bottom-level cell, which gives the leaf or the largest empty node containing it (nodeOf()'s
/// answer); where that node is an absent block's (or larger), the step crosses the block's empty
/// box instead (stepBox_: a box of absent blocks grown from that node, which a ray crosses in one
/// step where the octree would take several). It computes the region's exit face as the tree walk does (detail::planeCrossing,
/// nearestExit: ((c + 1) << s) csH is (c + 1) cs_l exactly, the cell sizes being the root's
/// extent times powers of two), and the next cell: an integer step on the exit axis, the other
/// axes from the exit point clamped into the node (so round-off cannot skip a node). No branch
/// depends on the tree: a step is the same instructions for a leaf and for any empty node, so
/// several rays' steps can be in flight at once (rays/batch_trace.h) without mispredictions
/// between them. The next cell's table entry and leaf range are asked for (prefetch) before the
/// caller tests this step's leaf.
class MatrixTree::TableWalk {
 public:
  /// What a step reads: the step table (bytes, per-pointer-cell block offsets), the leaf ranges,
  /// the per-level masks, and the bottom level's shape. The leaf level's pointer matrix has a
  /// power of two of cells along each axis (the level's 2^logDim cells over blocks of 8, or one),
  /// so a cell's pointer is ((z >> 3) << (lx + ly)) | ((y >> 3) << lx) | (x >> 3).
  struct Tables {
    const uint8_t* bytes;
    const uint32_t* blocks;
    const MtLeafRange* ranges;
    const std::array<int, 4>* mask;  // stepMask_: lane 3 is -1
    const uint64_t* boxes;           // stepBox_
    int boxLevel;                    // the block level: a node at it or above is an absent block's
    Box root;
    Vec3 invLeaf, cs;
    int dim[3];
    int logPx, logPy;
    int maxSteps;
  };
  /// Only where tree.hasStepTable().
  explicit MT_ALWAYS_INLINE TableWalk(const MatrixTree& t) {
    k_.bytes = t.stepLevel_.data();
    k_.blocks = t.stepBlock_.data();
    k_.ranges = t.leaves_.data().data();
    k_.mask = t.stepMask_.data();
    k_.boxes = t.stepBox_.data();
    k_.boxLevel = t.height_ - t.blockLevels_;
    k_.root = t.root_;
    k_.invLeaf = t.invLeaf_;
    k_.cs = t.cellSize_[t.height_];
    for (int a = 0; a < 3; ++a) k_.dim[a] = t.dim(t.height_, a);
    k_.logPx = t.stepLogPtr_[0];
    k_.logPy = t.stepLogPtr_[1];
    k_.maxSteps = 3 * (k_.dim[0] + k_.dim[1] + k_.dim[2]) + 8;
  }
  const Tables& tables() const { return k_; }
  /// Sets r up for the ray o + t d, t in [tmin, tmax]; false if it has no cell to walk (it misses
  /// the root box, or bad input: non-finite, zero direction, tmin > tmax or NaN).
  MT_ALWAYS_INLINE bool start(Vec3 o, Vec3 d, double tmin, double tmax, TableRay& r) const {
    detail::RayClip c;
    if (!c.clip(k_.root, o, d, tmin, tmax)) return false;
    for (int a = 0; a < 3; ++a) {
      r.o[a] = o[a] - k_.root.lo[a];
      r.d[a] = d[a];
      r.inv[a] = c.inv[a];
      r.never[a] = c.never[a];
      r.up[a] = c.up[a];
    }
    r.t1 = c.t1;
    r.te = c.t0;
    for (int a = 0; a < 3; ++a)
      r.L[a] = cellIndexNonNegative((r.o[a] + r.d[a] * c.t0) * k_.invLeaf[a], 0, k_.dim[a] - 1);
    r.p = pointer(r.L[0], r.L[1], r.L[2]);
    r.e = entry(r.p, r.L[0], r.L[1], r.L[2]);
    r.stepsLeft = k_.maxSteps;
    return true;
  }
  MT_ALWAYS_INLINE TableStep step(TableRay& r) const {
    const uint8_t v = k_.bytes[r.e];
    const int level = v & ~kStepLeaf;
    // The region the ray crosses, in bottom-level cells [lo, hi] per axis: the node, L with its
    // low bits cleared (lo) or set (hi); in an absent block, the block's empty box.
    const int* m = k_.mask[level].data();
    const uint64_t box = k_.boxes[r.p];
    const bool inBox = level <= k_.boxLevel;
    int lo[3], hi[3];
    double tx[3];
    for (int a = 0; a < 3; ++a) {
      const int bl = int((box >> (8 * a)) & 0xFF) << 3, bh = (int((box >> (8 * a + 32)) & 0xFF) << 3) | 7;
      lo[a] = inBox ? bl : r.L[a] & m[a];
      hi[a] = inBox ? bh : r.L[a] | ~m[a];
      tx[a] = detail::planeCrossing(r.up[a] ? hi[a] + 1 : lo[a], k_.cs[a], r.o[a], r.inv[a], r.never[a]);
    }
    TableStep out;
    const int ax = detail::nearestExit(tx[0], tx[1], tx[2], r.t1, out.tExit);
    out.tExit = std::max(out.tExit, r.te);
    out.tEnter = r.te;
    out.here = r.e;
    out.leaf = (v & kStepLeaf) != 0;
    int n[3];
    for (int a = 0; a < 3; ++a) {
      out.L[a] = r.L[a];
      // A bottom-level node has lo = hi: the clamp keeps its coordinate.
      n[a] = detail::clampCell((r.o[a] + r.d[a] * out.tExit) * k_.invLeaf[a], lo[a], hi[a]);
      n[a] = ax == a ? (r.up[a] ? hi[a] + 1 : lo[a] - 1) : n[a];
    }
    bool next = (ax >= 0) & (unsigned(n[0]) < unsigned(k_.dim[0])) & (unsigned(n[1]) < unsigned(k_.dim[1])) &
                (unsigned(n[2]) < unsigned(k_.dim[2])) & (--r.stepsLeft > 0);
    out.next = next;
    if (next) {
      for (int a = 0; a < 3; ++a) r.L[a] = n[a];
      r.p = pointer(n[0], n[1], n[2]);
      r.e = entry(r.p, n[0], n[1], n[2]);
      __builtin_prefetch(k_.ranges + r.e);
    }
    r.te = out.tExit;
    return out;
  }
  /// The primitive ids of the leaf at step-table entry `here` (a leaf's: TableStep::leaf).
  MtLeafRange leafRange(uint32_t here) const { return k_.ranges[here]; }
  /// The leaf pointer-matrix cell of bottom-level cell (x, y, z) (in range).
  MT_ALWAYS_INLINE uint32_t pointer(int x, int y, int z) const {
    return (uint32_t(z >> 3) << (k_.logPx + k_.logPy)) | (uint32_t(y >> 3) << k_.logPx) | uint32_t(x >> 3);
  }
  /// The step-table entry of bottom-level cell (x, y, z), p its pointer-matrix cell.
  MT_ALWAYS_INLINE uint32_t entry(uint32_t p, int x, int y, int z) const {
    return k_.blocks[p] + ((uint32_t(z & 7) << 6) | (uint32_t(y & 7) << 3) | uint32_t(x & 7));
  }

 private:
  Tables k_;
};

template <class LeafFn>
void MatrixTree::traverseRay(Vec3 o, Vec3 d, double tmin, double tmax, LeafFn&& fn,
                             TraversalStats* st) const {
  if (empty_) return;
  if (stepTableOn_ && hasStepTable()) {
    const TableWalk w(*this);
    TableRay r;
    if (!w.start(o, d, tmin, tmax, r)) return;
    auto walk = [&](auto counting) {
      for (;;) {
        const TableStep s = w.step(r);
        if constexpr (decltype(counting)::value) {
          ++st->nodeVisits;
          ++st->cells;
        }
        if (s.leaf) {
          const MtLeafRange lr = w.leafRange(s.here);
          if (detail::callLeaf(fn, prims_.data() + lr.begin, lr.end - lr.begin, s.tEnter, s.tExit, s.L[0], s.L[1],
                               s.L[2]))
            return;
        }
        if (!s.next) return;
      }
    };
    if (st) {
      walk(std::true_type{});
    } else {
      walk(std::false_type{});
    }
    return;
  }
  detail::RayClip clip;
  if (!clip.clip(root_, o, d, tmin, tmax)) return;
  const double* inv = clip.inv;
  const double* never = clip.never;
  const double t0 = clip.t0, t1 = clip.t1;
  const int H = height_;
  const Vec3 ol = o - root_.lo;  // local coordinates: the root box starts at 0
  int L[3];
  {
    const Vec3 p = ol + d * t0;
    for (int a = 0; a < 3; ++a)
      L[a] = cellIndexNonNegative(p[a] * invLeaf_[a], 0, dim(H, a) - 1);
  }
  double tEnter = t0;
  // The far face of the node with integer coordinate c and extent cs[a] on axis a: where the
  // ray leaves it along that axis (+inf on an axis it does not move along).
  auto exitPlane = [&](int a, int c, const Vec3& cs) {
    return detail::planeCrossing(c + (clip.up[a] ? 1 : 0), cs[a], ol[a], inv[a], never[a]);
  };
  // The exit plane of the node with integer coordinates c and extent cs.
  auto exitOf = [&](const int c[3], const Vec3& cs, double& tExit) -> int {
    return detail::nearestExit(exitPlane(0, c[0], cs), exitPlane(1, c[1], cs), exitPlane(2, c[2], cs), t1, tExit);
  };
  const int maxSteps = 3 * (dim(H, 0) + dim(H, 1) + dim(H, 2)) + 8;
  const Vec3 csH = cellSize_[H];
  const int dimH[3] = {dim(H, 0), dim(H, 1), dim(H, 2)};
  const bool fast = fastNodeOf();
  NodeRef n = fast ? nodeOf(L, st) : locate(L, 0, H + 1, st);
  int step = 0;
  for (; step < maxSteps; ++step) {
    if (n.level == H) {
      // A run of bottom-level cells (leaves and empty cells under an existing parent): L is the
      // node, the next cell is one integer step along the exit axis, and the exit plane is the
      // general loop's (exitPlane, nearestExit), so the walk is the same, with less
      // bookkeeping per step: the coordinates stay in registers (not the array that nodeOf and
      // bottomCell read, written back only when the run ends), the step is branch-free, and
      // bottomCell is inlined (1.3-1.7% of a surface ray, locator_ab-style alternation).
      int Lx = L[0], Ly = L[1], Lz = L[2];
      const int sx = clip.up[0] ? 1 : -1, sy = clip.up[1] ? 1 : -1, sz = clip.up[2] ? 1 : -1;
      double tx = exitPlane(0, Lx, csH), ty = exitPlane(1, Ly, csH), tz = exitPlane(2, Lz, csH);
      bool larger = false;  // n became a larger empty node
      for (; step < maxSteps; ++step) {
        if (st) ++st->cells;
        double tExit;
        const int ax = detail::nearestExit(tx, ty, tz, t1, tExit);
        tExit = std::max(tExit, tEnter);
        if (n.exists &&
            detail::callLeaf(fn, prims_.data() + n.range.begin, n.range.end - n.range.begin, tEnter, tExit, Lx, Ly, Lz))
          return;
        if (ax < 0) return;
        Lx += ax == 0 ? sx : 0;
        Ly += ax == 1 ? sy : 0;
        Lz += ax == 2 ? sz : 0;
        if ((unsigned(Lx) >= unsigned(dimH[0])) | (unsigned(Ly) >= unsigned(dimH[1])) | (unsigned(Lz) >= unsigned(dimH[2])))
          return;
        tx = exitPlane(0, Lx, csH);
        ty = exitPlane(1, Ly, csH);
        tz = exitPlane(2, Lz, csH);
        tEnter = tExit;
        const int Lc[3] = {Lx, Ly, Lz};
        const int cell = bottomCell(Lc, n.range, st);
        n.exists = cell > 0;
        if (cell >= 0) continue;
        // The parent is absent: the largest empty node containing L, above level H - 1.
        L[0] = Lx;
        L[1] = Ly;
        L[2] = Lz;
        n = fast ? nodeOf(L, st) : searchAbove(L, H - 1, st);
        if (n.level != H) {
          larger = true;
          break;
        }
      }
      if (!larger) return;  // out of steps
      continue;             // n is a larger empty node containing L: the general step below
    }
    if (st) ++st->cells;
    double tExit;
    const int exitAxis = exitOf(n.c, cellSize_[n.level], tExit);
    tExit = std::max(tExit, tEnter);
    if (n.exists) {
      // An existing node is a leaf (level H): n.c are its bottom-level coordinates.
      if (detail::callLeaf(fn, prims_.data() + n.range.begin, n.range.end - n.range.begin, tEnter, tExit, n.c[0],
                           n.c[1], n.c[2]))
        return;
    }
    if (exitAxis < 0) return;  // the ray interval ends inside this node
    // Bottom-level cell just across the exit face: exact integer step on the exit axis, the
    // other axes from the exit point, clamped into this node so round-off cannot skip a node.
    const int sh = logDims_[H][exitAxis] - logDims_[n.level][exitAxis];
    const int dir = d[exitAxis] > 0 ? 1 : -1;
    L[exitAxis] = dir > 0 ? ((n.c[exitAxis] + 1) << sh) : ((n.c[exitAxis] << sh) - 1);
    if (L[exitAxis] < 0 || L[exitAxis] >= dim(H, exitAxis)) return;
    for (int a = 0; a < 3; ++a) {
      if (a == exitAxis) continue;
      const int s = logDims_[H][a] - logDims_[n.level][a];
      const int lo = n.c[a] << s, hi = ((n.c[a] + 1) << s) - 1;
      L[a] = cellIndexNonNegative((ol[a] + d[a] * tExit) * invLeaf_[a], lo, hi);
    }
    n = fast ? nodeOf(L, st) : neighbourFind(n, exitAxis, dir, L, st);
    if (n.level < 0) return;
    tEnter = tExit;
  }
}

}  // namespace mtree
