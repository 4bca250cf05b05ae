#include "mtree/core/matrix_tree.h"

#include <cstring>

namespace mtree {

const char* treeKindName(TreeKind k) { return k == TreeKind::Octree ? "octree" : "kdtree"; }

namespace {
// One level down: which axes split (the tree kind's rule, see matrix_tree.h). Updates the node
// extent `cell` and the per-axis log2 node counts `s`. The one place the rule is written, so the
// level shapes and the automatic height can never disagree.
void splitLevel(TreeKind kind, Vec3& cell, std::array<int, 3>& s) {
  const double m = std::max(cell.x, std::max(cell.y, cell.z));
  if (kind == TreeKind::Octree) {
    for (int a = 0; a < 3; ++a)
      if (cell[a] * 2.0 > m) { ++s[a]; cell[a] *= 0.5; }
  } else {
    const int a = (cell.x >= cell.y && cell.x >= cell.z) ? 0 : (cell.y >= cell.z ? 1 : 2);
    ++s[a];
    cell[a] *= 0.5;
  }
}
}  // namespace

std::vector<std::array<int, 3>> levelShapes(TreeKind kind, Vec3 e, int height) {
  std::vector<std::array<int, 3>> shapes(static_cast<size_t>(height) + 1, std::array<int, 3>{0, 0, 0});
  Vec3 cell = e;
  for (int l = 1; l <= height; ++l) {
    shapes[l] = shapes[l - 1];
    splitLevel(kind, cell, shapes[l]);
  }
  return shapes;
}

int chooseHeight(TreeKind kind, Vec3 rootExtent, double medianExtent, double leafScale, int blockEdge) {
  const double target = leafScale * medianExtent;
  // Deep enough for the target leaf size, but the leaf level's dense pointer matrix stays at most
  // 2^24 cells (64 MiB), and no axis gets more than 2^30 nodes.
  const int lb = ceilLog2(static_cast<uint64_t>(std::max(blockEdge, 1)));
  constexpr int kMaxLogPointers = 24, kMaxLogAxis = 30;
  const int maxH = kind == TreeKind::Octree ? 24 : MT_MAX_LEVELS - 1;
  Vec3 cell = rootExtent;
  int h = 0;
  std::array<int, 3> s{0, 0, 0};
  while (h < maxH) {
    const double m = std::max(cell.x, std::max(cell.y, cell.z));
    if (!(target > 0) || m <= target) break;
    std::array<int, 3> ns = s;
    Vec3 nc = cell;
    splitLevel(kind, nc, ns);
    int logPtr = 0;
    for (int a = 0; a < 3; ++a) logPtr += std::max(0, ns[a] - lb);
    if (logPtr > kMaxLogPointers || std::max(ns[0], std::max(ns[1], ns[2])) > kMaxLogAxis) break;
    s = ns;
    cell = nc;
    ++h;
  }
  return h;
}

void MatrixTree::buildWalkCaches(int threads) {
  leafMask_.clear();
  levelBits_.clear();
  blockEmpty_.clear();
  blockLevels_ = 0;
  denseLevels_ = 0;
  stepLevel_.clear();
  stepBlock_.clear();
  stepBox_.clear();
  if (empty_) return;
  // Dense bits of the upper levels, from the root down while they stay no larger than the
  // level's block-sparse bytes (levels only grow going down).
  size_t words = 0;
  for (int l = 0; l < height_; ++l) {
    const int sum = logDims_[l][0] + logDims_[l][1] + logDims_[l][2];
    if (sum > 30) break;
    const uint64_t bits = uint64_t(1) << sum;
    if (bits / 8 > inner_[l].bytes()) break;
    dense_[l].offset = words;
    dense_[l].lx = logDims_[l][0];
    dense_[l].ly = logDims_[l][1];
    words += static_cast<size_t>((bits + 63) / 64);
    denseLevels_ = l + 1;
  }
  levelBits_.assign(words, 0);
  for (int l = 0; l < denseLevels_; ++l) {
    const BlockSparseMatrix<uint8_t>& m = inner_[l];
    const uint8_t* v = m.data().data();
    const int64_t ne = static_cast<int64_t>(m.data().size());
    for (int64_t e = 0; e < ne; ++e) {
      if (!v[e]) continue;
      int c[3];
      m.entryCoords(static_cast<uint32_t>(e), c);
      const uint64_t i = denseBit(l, c);
      levelBits_[i >> 6] |= uint64_t(1) << (i & 63);
    }
  }
  const MtSparseDesc& d = leaves_.desc();
  if (d.logBlock[0] != 3 || d.logBlock[1] != 3 || d.logBlock[2] != 3) return;
  // The sibling pattern of the last split: the axes that split between level H-1 and H.
  const int H = height_;
  int split[3] = {0, 0, 0};
  if (H > 0)
    for (int a = 0; a < 3; ++a) split[a] = logDims_[H][a] - logDims_[H - 1][a];
  const uint64_t xBits = split[0] ? 0x3u : 0x1u;
  siblingBits_ = split[1] ? (xBits | (xBits << 8)) : xBits;
  siblingZ_ = split[2] != 0;
  for (int a = 0; a < 3; ++a) siblingLow_[a] = split[a] ? ~1 : ~0;
  const int64_t nb = leaves_.numBlocks();
  leafMask_.assign(static_cast<size_t>(nb) * 8, 0);
  const MtLeafRange* data = leaves_.data().data();
  uint64_t* out = leafMask_.data();
#pragma omp parallel for num_threads(resolveThreads(threads)) schedule(static) if (nb > 256)
  for (int64_t b = 0; b < nb; ++b) {
    const MtLeafRange* r = data + b * 512;
    for (int z = 0; z < 8; ++z) {
      uint64_t w = 0;
      for (int k = 0; k < 64; ++k) w |= uint64_t(r[z * 64 + k].begin != MT_NULL) << k;
      out[b * 8 + z] = w;
    }
  }
  buildBlockEmpty();
  buildStepTable(threads);
}

namespace {
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the step table writes byte i of a word as cell i");
// The low 8 bits of m as 8 bytes of 0 or 1 (byte i = bit i), little-endian: m copied into every
// byte, byte i keeps bit i, and adding 0x7F moves any set bit to the byte's top bit.
inline uint64_t spreadBits(uint64_t m) {
  const uint64_t x = (m & 0xFF) * 0x0101010101010101ull & 0x8040201008040201ull;
  return ((x + 0x7F7F7F7F7F7F7F7Full) >> 7) & 0x0101010101010101ull;
}
}  // namespace

void MatrixTree::buildStepTable(int threads) {
  if (blockEmpty_.empty() || leafMask_.empty()) return;
  const int H = height_;
  const int64_t nb = leaves_.numBlocks();
  // Offsets are 32-bit, like the leaf level's storage indices.
  if (H >= kStepLeaf || (uint64_t(nb) + uint64_t(H) + 1) * 512 > uint64_t(MT_NULL)) return;
  // Worth its 512 bytes per block only where rays cross empty cells of the allocated blocks: a
  // volume mesh's blocks are nearly all leaves (there the walk is 15-22% of a ray, and the
  // masks answer a leaf in one probe), a surface's are mostly empty.
  uint64_t leaves = 0;
  for (const uint64_t w : leafMask_) leaves += static_cast<uint64_t>(__builtin_popcountll(w));
  if (2 * leaves > uint64_t(nb) * 512) return;
  for (int l = 0; l <= H; ++l) {
    for (int a = 0; a < 3; ++a) {
      stepShift_[l][a] = logDims_[H][a] - logDims_[l][a];
      stepMask_[l][a] = ~((1 << stepShift_[l][a]) - 1);
    }
    stepMask_[l][3] = -1;
  }
  // The walk computes pointer-matrix indices with shifts: a power of two of cells per axis.
  for (int a = 0; a < 2; ++a) {
    const int cells = int(leaves_.desc().ptrDims[a]);
    int lg = 0;
    while ((1 << lg) < cells) ++lg;
    if ((1 << lg) != cells) return;
    stepLogPtr_[a] = lg;
  }
  // Per block, nested fills of the leaf bits: fill[k] has a cell's bit set when its ancestor at
  // level H - k holds a leaf (k = 1 .. blockLevels_, each a union of aligned groups of cells:
  // the children's footprints merged along the axes split between the two levels). An empty
  // cell's node is the child of its first such ancestor: level H - k + 1 for the least k, i.e.
  // H minus the number of fills that miss it (they are nested). Eight cells at a time in bytes.
  const int K = blockLevels_;
  constexpr uint64_t kOnes = 0x0101010101010101ull;
  // Aligned pairs of runs of 2^j cells: the lower runs' bits of a mask word along x (j < 3,
  // within a row of 8) and along y (rows of 8 bits).
  static constexpr uint64_t kLowX[3] = {0x5555555555555555ull, 0x3333333333333333ull, 0x0F0F0F0F0F0F0F0Full};
  static constexpr uint64_t kLowY[3] = {0x00FF00FF00FF00FFull, 0x0000FFFF0000FFFFull, 0x00000000FFFFFFFFull};
  std::vector<uint8_t> bytes(size_t(nb + H + 1) * 512);
  bool complete = true;
#pragma omp parallel for num_threads(resolveThreads(threads)) schedule(static) if (nb > 256) reduction(&& : complete)
  for (int64_t b = 0; b < nb; ++b) {
    const uint64_t* w = leafMask_.data() + b * 8;
    uint64_t fill[8], missed[64];  // missed: per 8 cells, the count of fills that miss each (bytes)
    for (int z = 0; z < 8; ++z) fill[z] = w[z];
    for (int q = 0; q < 64; ++q) missed[q] = 0;
    for (int k = 1; k <= K; ++k) {
      const int lower = H - k + 1;  // the fills grow from level `lower`'s footprints to its parent's
      for (int a = 0; a < 3; ++a) {
        const int j = stepShift_[lower][a];
        if (stepShift_[lower - 1][a] == j) continue;  // not split between the two levels
        if (a == 2) {  // z: the pair's words
          uint64_t merged[8];
          for (int z = 0; z < 8; ++z) merged[z] = fill[z] | fill[z ^ (1 << j)];
          for (int z = 0; z < 8; ++z) fill[z] = merged[z];
          continue;
        }
        // x or y: within each word, runs of 2^j bits (x) or of 2^j rows of 8 (y).
        const int shift = a == 0 ? 1 << j : 8 << j;
        const uint64_t low = a == 0 ? kLowX[j] : kLowY[j];
        for (int z = 0; z < 8; ++z) {
          const uint64_t v = fill[z];
          fill[z] = v | ((v & low) << shift) | ((v >> shift) & low);
        }
      }
      for (int q = 0; q < 64; ++q) missed[q] += ~spreadBits(fill[q >> 3] >> (8 * (q & 7))) & kOnes;
    }
    // The block fill (k = K) covers the block: a cell it misses means a block without leaves.
    uint64_t all = 0;
    for (int z = 0; z < 8; ++z) all |= ~fill[z];
    complete = complete && all == 0;
    uint8_t* out = bytes.data() + b * 512;
    for (int q = 0; q < 64; ++q) {
      const uint64_t leaf = spreadBits(w[q >> 3] >> (8 * (q & 7)));
      const uint64_t v = (uint64_t(H) * kOnes - missed[q]) | (leaf << 7);
      std::memcpy(out + 8 * q, &v, 8);
    }
  }
  if (!complete) return;
  for (int l = 0; l <= H; ++l) std::fill_n(bytes.data() + size_t(nb + l) * 512, 512, static_cast<uint8_t>(l));
  const std::vector<uint32_t>& ptr = leaves_.pointers();
  std::vector<uint32_t> blocks(ptr.size());
  for (size_t p = 0; p < ptr.size(); ++p)
    blocks[p] = static_cast<uint32_t>((ptr[p] != MT_NULL ? uint64_t(ptr[p]) : uint64_t(nb) + blockEmpty_[p]) * 512);
  stepLevel_.swap(bytes);
  stepBlock_.swap(blocks);
  buildStepBoxes();
}

void MatrixTree::buildStepBoxes() {
  // Block units, one byte per coordinate: the pointer matrix has at most 256 cells per axis.
  const MtSparseDesc& d = leaves_.desc();
  const int n[3] = {d.ptrDims[0], d.ptrDims[1], d.ptrDims[2]};
  const std::vector<uint32_t>& ptr = leaves_.pointers();
  if (n[0] > 256 || n[1] > 256 || n[2] > 256) {  // no boxes, and so no table
    stepLevel_.clear();
    stepBlock_.clear();
    return;
  }
  stepBox_.assign(ptr.size(), 0);
  auto pack = [](const int lo[3], const int hi[3]) {
    uint64_t v = 0;
    for (int a = 0; a < 3; ++a) v |= (uint64_t(lo[a]) << (8 * a)) | (uint64_t(hi[a]) << (8 * a + 32));
    return v;
  };
  auto at = [&](int x, int y, int z) { return (size_t(z) * size_t(n[1]) + size_t(y)) * size_t(n[0]) + size_t(x); };
  // Allocated blocks per box in O(1): a summed-volume table over the pointer matrix.
  std::vector<uint32_t> sum;
  const size_t sx = size_t(n[0]) + 1, sy = size_t(n[1]) + 1;
  auto S = [&](int x, int y, int z) -> uint32_t& { return sum[(size_t(z) * sy + size_t(y)) * sx + size_t(x)]; };
  sum.assign(sx * sy * (size_t(n[2]) + 1), 0);
  for (int z = 1; z <= n[2]; ++z)
    for (int y = 1; y <= n[1]; ++y)
      for (int x = 1; x <= n[0]; ++x)
        S(x, y, z) = uint32_t(ptr[at(x - 1, y - 1, z - 1)] != MT_NULL) + S(x - 1, y, z) + S(x, y - 1, z) +
                     S(x, y, z - 1) - S(x - 1, y - 1, z) - S(x - 1, y, z - 1) - S(x, y - 1, z - 1) +
                     S(x - 1, y - 1, z - 1);
  auto allocated = [&](const int lo[3], const int hi[3]) {  // blocks allocated in [lo, hi]
    const int x0 = lo[0], y0 = lo[1], z0 = lo[2], x1 = hi[0] + 1, y1 = hi[1] + 1, z1 = hi[2] + 1;
    return S(x1, y1, z1) - S(x0, y1, z1) - S(x1, y0, z1) - S(x1, y1, z0) + S(x0, y0, z1) + S(x0, y1, z0) +
           S(x1, y0, z0) - S(x0, y0, z0);
  };
  for (int z = 0; z < n[2]; ++z)
    for (int y = 0; y < n[1]; ++y)
      for (int x = 0; x < n[0]; ++x) {
        const size_t p = at(x, y, z);
        const int c[3] = {x, y, z};
        if (ptr[p] != MT_NULL) {
          stepBox_[p] = pack(c, c);
          continue;
        }
        // The largest empty node containing the block, in block units (its levels are above the
        // block's, H - 3). Every block of that node gets the same box: computed at the node's
        // low corner, the first of its blocks in this order, and copied for the others.
        const int level = blockEmpty_[p];
        int lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
          const int s = stepShift_[level][a] - 3;
          lo[a] = (c[a] >> s) << s;
          hi[a] = lo[a] + (1 << s) - 1;
        }
        const size_t first = at(lo[0], lo[1], lo[2]);
        if (first != p) {
          stepBox_[p] = stepBox_[first];
          continue;
        }
        // Grown one slab of blocks at a time, the six faces in turn, while the slab holds no
        // allocated block: a maximal empty box (not the largest one: a greedy choice).
        for (bool grew = true; grew;) {
          grew = false;
          for (int f = 0; f < 6; ++f) {
            const int a = f >> 1;
            const bool upward = f & 1;
            if (upward ? hi[a] + 1 >= n[a] : lo[a] == 0) continue;
            int slo[3] = {lo[0], lo[1], lo[2]}, shi[3] = {hi[0], hi[1], hi[2]};
            slo[a] = shi[a] = upward ? hi[a] + 1 : lo[a] - 1;
            if (allocated(slo, shi) != 0) continue;
            (upward ? hi[a] : lo[a]) = slo[a];
            grew = true;
          }
        }
        stepBox_[p] = pack(lo, hi);
      }
}

void MatrixTree::buildBlockEmpty() {
  // nodeOf() needs every level's nodes to lie inside one 8x8x8 leaf block or to be unions of
  // whole blocks: per level, the bottom-level cells per node are 2^s[a] along axis a, all s[a]
  // <= 3 or all >= 3. Octrees with a cubic or a flat root qualify; a regular kd-tree may split
  // one axis twice in a row near the bottom, and then keeps the searches.
  const int H = height_;
  int blockLevel = -1;
  for (int l = H; l >= 0; --l) {
    int s[3];
    for (int a = 0; a < 3; ++a) s[a] = logDims_[H][a] - logDims_[l][a];
    const bool inside = s[0] <= 3 && s[1] <= 3 && s[2] <= 3, whole = s[0] >= 3 && s[1] >= 3 && s[2] >= 3;
    if (!inside && !whole) return;
    if (inside && whole) blockLevel = l;
  }
  const int k = H - blockLevel;
  const std::vector<uint32_t>& ptr = leaves_.pointers();
  // Bounded work and memory: a byte per pointer-matrix cell and a pass over the levels above.
  if (blockLevel < 0 || k < 1 || k >= static_cast<int>(group_.size()) || ptr.size() > (size_t{1} << 21)) return;
  for (int g = 1; g <= k; ++g) {
    int s[3];
    for (int a = 0; a < 3; ++a) s[a] = logDims_[H][a] - logDims_[H - g][a];
    const uint64_t row = (uint64_t{1} << (1 << s[0])) - 1;  // 2^s0 <= 8 bits
    uint64_t bits = 0;
    for (int y = 0; y < (1 << s[1]); ++y) bits |= row << (8 * y);
    group_[g].bits = bits;
    for (int a = 0; a < 3; ++a) group_[g].low[a] = ~((1 << s[a]) - 1);
    group_[g].depth = 1 << s[2];
  }
  // Top down to the block level: the level of the largest empty node containing each node, or
  // 0xFF where it exists (a node exists iff its parent does and its own entry says so).
  std::vector<uint8_t> above(1, 0xFF), here;
  for (int l = 1; l <= blockLevel; ++l) {
    const int lx = logDims_[l][0], ly = logDims_[l][1], lz = logDims_[l][2];
    int sh[3];
    for (int a = 0; a < 3; ++a) sh[a] = logDims_[l][a] - logDims_[l - 1][a];
    const int px = logDims_[l - 1][0], py = logDims_[l - 1][1];
    here.assign(size_t{1} << (lx + ly + lz), 0);
    for (int z = 0; z < (1 << lz); ++z)
      for (int y = 0; y < (1 << ly); ++y)
        for (int x = 0; x < (1 << lx); ++x) {
          const size_t parent = ((size_t(z >> sh[2]) << py | size_t(y >> sh[1])) << px) | size_t(x >> sh[0]);
          const int c[3] = {x, y, z};
          uint8_t v = above[parent];
          if (v == 0xFF) v = innerExists(l, c) ? uint8_t(0xFF) : static_cast<uint8_t>(l);
          here[(size_t(z) << ly | size_t(y)) << lx | size_t(x)] = v;
        }
    above.swap(here);
  }
  // The block level's nodes are the pointer matrix's cells, in its order (x fastest).
  if (above.size() != ptr.size()) return;
  for (size_t p = 0; p < ptr.size(); ++p)
    if (ptr[p] == MT_NULL && above[p] == 0xFF) return;  // an absent block under an existing node
  blockEmpty_.swap(above);
  blockLevels_ = k;
}

size_t MatrixTree::bytes() const {
  size_t b = prims_.size() * sizeof(uint32_t) + leaves_.bytes() + walkCacheBytes();
  for (const auto& m : inner_) b += m.bytes();
  return b;
}

uint64_t MatrixTree::numLeaves() const {
  uint64_t n = 0;
  for (const MtLeafRange& r : leaves_.data()) n += (r.begin != MT_NULL);
  return n;
}

NodeRef MatrixTree::leafFind(Vec3 p, TraversalStats* st) const {
  int L[3];
  if (!leafCoords(p, L)) return NodeRef{};
  return locate(L, 0, height_ + 1, st);
}

NodeRef MatrixTree::leafFindTopDown(Vec3 p) const {
  int L[3];
  if (!leafCoords(p, L)) return NodeRef{};
  NodeRef r;
  for (int l = 1; l <= height_; ++l) {
    ancestor(L, l, r.c);
    if (!nodeExists(l, r.c)) {
      r.level = l;
      return r;
    }
  }
  r.level = height_;
  ancestor(L, height_, r.c);
  r.exists = true;
  return r;
}

}  // namespace mtree
