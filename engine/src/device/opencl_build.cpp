// OpenCL host code, part 2: the §5.1 build on the device (kernels in opencl/build.cl, scan.cl,
// sort.cl), producing the same MatrixTree as MatrixTreeBuilder<TriangleMesh> (builder.h).
//
// The serial setup (root box padding, automatic height, level shapes) runs on the host and
// repeats builder.h's arithmetic; the root box itself is a device reduction. After the build
// the tree is copied into a host MatrixTree: the block pointers are re-derived from the device's
// block marks by BlockSparseMatrix::allocateMarked (the same scan the device ran; tests compare
// the two pointer arrays), the blocks, leaf ranges and triangle order are copied as they are.
#ifdef MATRIXTREE_HAVE_OPENCL

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "mtree/core/builder.h"
#include "opencl_internal.h"

namespace mtree {
namespace ocl {
namespace detail {
/// Tag type: its MatrixTreeBuilder specialisation below is the OpenCL builder's way into
/// MatrixTree's storage (MatrixTree befriends every MatrixTreeBuilder<...>).
struct DeviceTriangles {};
}  // namespace detail
}  // namespace ocl

template <>
class MatrixTreeBuilder<ocl::detail::DeviceTriangles> {
 public:
  static TreeKind& kind(MatrixTree& t) { return t.kind_; }
  static int& height(MatrixTree& t) { return t.height_; }
  static int& blockEdge(MatrixTree& t) { return t.blockEdge_; }
  static bool& empty(MatrixTree& t) { return t.empty_; }
  static Box& root(MatrixTree& t) { return t.root_; }
  static Vec3& invLeaf(MatrixTree& t) { return t.invLeaf_; }
  static std::vector<std::array<int, 3>>& logDims(MatrixTree& t) { return t.logDims_; }
  static std::vector<Vec3>& cellSize(MatrixTree& t) { return t.cellSize_; }
  static std::vector<BlockSparseMatrix<uint8_t>>& inner(MatrixTree& t) { return t.inner_; }
  static BlockSparseMatrix<MtLeafRange>& leaves(MatrixTree& t) { return t.leaves_; }
  static LargeVector<uint32_t>& prims(MatrixTree& t) { return t.prims_; }
};

namespace ocl {
namespace {
using Access = MatrixTreeBuilder<detail::DeviceTriangles>;

struct PhaseClock {
  using clock = std::chrono::steady_clock;
  clock::time_point start = clock::now(), last = start;
  BuildStats* stats;
  Launcher* run;
  void lap(const char* name) {
    run->finish();  // the phase ends when the device is done with it
    const auto now = clock::now();
    if (stats) stats->phasesMs.emplace_back(name, std::chrono::duration<double, std::milli>(now - last).count());
    last = now;
  }
  void finish() {
    if (stats) stats->totalMs = std::chrono::duration<double, std::milli>(clock::now() - start).count();
  }
};

uint32_t tilesOf(uint64_t n, int wg) { return static_cast<uint32_t>((n + uint64_t(wg) * 8 - 1) / (uint64_t(wg) * 8)); }
}  // namespace

struct Builder::State {
  Buffer pts, tris, groupBox, params, counts, masks, marks, leafPtr, leafBlockPos, offsets, keys, values, tmpKeys,
      tmpValues, hist, histScan, leafData, leafCount, tileSums, tileOffsets;
  struct Level {
    Buffer marks, ptr, blockPos, data;
  };
  std::vector<Level> levels;  // inner levels 0..H-1
  bool keepPointers = false;
  std::vector<std::vector<uint32_t>> devicePointers;
};

Builder::Builder(std::shared_ptr<Context> ctx) : ctx_(ctx ? std::move(ctx) : Context::shared()), st_(new State) {}
Builder::~Builder() = default;
Context& Builder::context() const { return *ctx_; }
void Builder::keepDevicePointers(bool on) { st_->keepPointers = on; }
const std::vector<std::vector<uint32_t>>& Builder::devicePointers() const { return st_->devicePointers; }

namespace {
/// Exclusive scan of n elements (uchar or uint) of `in` into `out` on the device; returns the
/// total. The tile sums are scanned on the host in 64 bits (see opencl/scan.cl).
uint64_t scanOnDevice(Context::Impl& impl, Launcher& run, Buffer& tileSums,
                      Buffer& tileOffsets, const Buffer& in, bool bytes, const Buffer& out, uint32_t n,
                      const char* what) {
  if (n == 0) return 0;
  const uint32_t tiles = tilesOf(n, impl.wg);
  tileSums.ensure(impl, sizeof(uint64_t) * tiles, "scan tile sums");
  tileOffsets.ensure(impl, sizeof(uint32_t) * tiles, "scan tile offsets");
  run.run(bytes ? "mt_scan_tiles_u8" : "mt_scan_tiles_u32", size_t(tiles) * impl.wg, size_t(impl.wg), in, out, n,
          tileSums);
  std::vector<uint64_t> sums(tiles);
  run.read(tileSums, sums.data(), sizeof(uint64_t) * tiles, "scan tile sums");
  std::vector<uint32_t> offs(tiles);
  uint64_t total = 0;
  for (uint32_t t = 0; t < tiles; ++t) {
    if (total >= MT_NULL) break;
    offs[t] = static_cast<uint32_t>(total);
    total += sums[t];
  }
  if (total >= MT_NULL)
    throw std::length_error(std::string("MatrixTree (OpenCL): the scan of ") + what +
                            " passes 2^32; lower the height or use the bounding-box overlap off");
  if (tiles > 1) {
    run.write(tileOffsets, offs.data(), sizeof(uint32_t) * tiles, "scan tile offsets");
    run.run("mt_scan_add", n, 0, out, n, tileOffsets);
  }
  return total;
}
}  // namespace

void Builder::build(const TriangleMesh& mesh, const BuildOptions& opt, MatrixTree& tree, BuildStats* stats,
                    std::vector<KernelTiming>* kernels) {
  // Options are checked exactly as the CPU builder checks them.
  mtree::detail::checkBuildOptions(opt, mesh.size());
  if (mesh.numPoints() * 3 > (uint64_t(1) << 31))
    throw std::length_error("MatrixTree (OpenCL): more than 2^31 coordinates");

  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  State& S = *st_;
  const int threads = resolveThreads(opt.threads);
  if (stats) *stats = BuildStats{};
  Launcher run(impl, kernels);
  PhaseClock clock{};
  clock.stats = stats;
  clock.run = &run;
  const uint32_t n = static_cast<uint32_t>(mesh.size());

  // A build that throws leaves an empty tree.
  Access::empty(tree) = true;
  tree.buildWalkCaches(0);  // clears them: an empty tree has none
  Access::prims(tree).clear();
  Access::root(tree) = Box{};
  Access::invLeaf(tree) = Vec3();
  Access::kind(tree) = opt.kind;
  Access::blockEdge(tree) = opt.blockEdge;
  S.devicePointers.clear();
  if (stats) stats->primitives = n;
  if (n == 0) {
    Access::height(tree) = 0;
    Access::inner(tree).clear();
    Access::logDims(tree).assign(1, {0, 0, 0});
    Access::cellSize(tree).assign(1, Vec3(1, 1, 1));
    Access::leaves(tree).reset(1, 1, 1, opt.blockEdge, MtLeafRange{MT_NULL, MT_NULL});
    clock.lap("setup");
    clock.finish();
    return;
  }

  // ---- upload ---------------------------------------------------------------------------------
  S.pts.ensure(impl, mesh.points().size() * sizeof(double), "vertices");
  S.tris.ensure(impl, mesh.triangles().size() * sizeof(uint32_t), "triangles");
  run.write(S.pts, mesh.points().data(), mesh.points().size() * sizeof(double), "vertices");
  run.write(S.tris, mesh.triangles().data(), mesh.triangles().size() * sizeof(uint32_t), "triangles");
  clock.lap("upload");

  // ---- setup: root box on the device, height and level shapes on the host ----------------------
  Box root;
  {
    const uint32_t groups = std::max<uint32_t>(1, std::min<uint32_t>(256, (n + impl.wg - 1) / impl.wg));
    S.groupBox.ensure(impl, sizeof(double) * 6 * groups, "bounds");
    run.run("mt_bounds", size_t(groups) * impl.wg, size_t(impl.wg), S.pts, S.tris, n, S.groupBox);
    std::vector<double> gb(6 * groups);
    run.read(S.groupBox, gb.data(), gb.size() * sizeof(double), "bounds");
    for (uint32_t g = 0; g < groups; ++g) {
      Box b;
      b.lo = Vec3(&gb[6 * g]);
      b.hi = Vec3(&gb[6 * g + 3]);
      root.extend(b);
    }
  }
  if (!(isFinite(root.lo) && isFinite(root.hi)))
    throw std::invalid_argument("MatrixTree: a primitive has non-finite coordinates (NaN or inf)");
  // From here to the level shapes: builder.h's setup (the same functions).
  root = mtree::detail::padRootBox(root);
  const Vec3 ext = root.extent();
  int H = opt.height;
  if (H == 0) {
    double med = 0;
    H = mtree::detail::autoHeight(mesh, opt, root, med);
    if (stats) {
      stats->autoHeight = true;
      stats->medianPrimitiveExtent = med;
    }
  }
  std::vector<std::array<int, 3>> logDims = levelShapes(opt.kind, ext, H);
  {
    const int lb = ceilLog2(static_cast<uint64_t>(opt.blockEdge));
    int logPtr = 0, logAxis = 0;
    for (int a = 0; a < 3; ++a) {
      logPtr += std::max(0, logDims[H][a] - lb);
      logAxis = std::max(logAxis, logDims[H][a]);
    }
    if (logPtr + 2 > 30 || logAxis > 30)
      throw std::length_error("MatrixTree: height " + std::to_string(H) + " needs a 2^" + std::to_string(logPtr + 2) +
                              "-byte pointer matrix at the leaf level (limit 1 GiB, and at most 2^30 nodes per "
                              "axis); lower the height or raise the block edge");
  }
  std::vector<Vec3> cellSize(H + 1);
  for (int l = 0; l <= H; ++l)
    for (int a = 0; a < 3; ++a) cellSize[l][a] = std::ldexp(ext[a], -logDims[l][a]);
  Vec3 invLeaf;
  for (int a = 0; a < 3; ++a) invLeaf[a] = std::ldexp(1.0, logDims[H][a]) / ext[a];
  const int nx = 1 << logDims[H][0], ny = 1 << logDims[H][1], nz = 1 << logDims[H][2];
  BlockSparseMatrix<MtLeafRange>& leaves = Access::leaves(tree);
  leaves.reset(nx, ny, nz, opt.blockEdge, MtLeafRange{MT_NULL, MT_NULL});
  const MtSparseDesc leafDesc = leaves.desc();
  const Vec3 leafSize = cellSize[H];
  const double pad = 64 * std::numeric_limits<double>::epsilon() *
                     std::max({std::fabs(root.lo.x), std::fabs(root.lo.y), std::fabs(root.lo.z),
                               std::fabs(root.hi.x), std::fabs(root.hi.y), std::fabs(root.hi.z)});
  const bool exact = opt.overlap == OverlapMode::Exact;
  MtBuildParams params;
  for (int a = 0; a < 3; ++a) {
    params.origin[a] = root.lo[a];
    params.invLeaf[a] = invLeaf[a];
    params.leafSize[a] = leafSize[a];
    params.halfSize[a] = 0.5 * leafSize[a] + pad;
  }
  S.params.ensure(impl, sizeof params, "build parameters");
  run.write(S.params, &params, sizeof params, "build parameters");
  if (stats) stats->height = H;
  clock.lap("setup");

  // ---- count + mark (step 2) ------------------------------------------------------------------
  const uint32_t ptrCount = static_cast<uint32_t>(leaves.pointerCount());
  S.counts.ensure(impl, sizeof(uint32_t) * n, "counts");
  S.masks.ensure(impl, exact ? sizeof(uint64_t) * n : 16, "masks");
  S.marks.ensure(impl, ptrCount, "leaf block marks");
  const uint8_t zero8 = 0;
  run.fill(S.marks, &zero8, 1, ptrCount, "leaf block marks");
  const cl_int exactArg = exact ? 1 : 0;
  run.run("mt_count_mark", n, 0, S.pts, S.tris, n, S.params, leafDesc, exactArg, S.counts, S.masks, S.marks);
  clock.lap("count+mark");

  // ---- allocate blocks (steps 3-4) ------------------------------------------------------------
  S.leafPtr.ensure(impl, sizeof(uint32_t) * ptrCount, "leaf pointers");
  const uint64_t numBlocks =
      scanOnDevice(impl, run, S.tileSums, S.tileOffsets, S.marks, true, S.leafPtr, ptrCount, "leaf block marks");
  if (numBlocks * leafDesc.blockVolume >= MT_NULL) throw std::length_error("BlockSparseMatrix: too many blocks");
  S.leafBlockPos.ensure(impl, sizeof(uint32_t) * numBlocks, "leaf block positions");
  run.run("mt_finish_alloc", ptrCount, 0, S.marks, S.leafPtr, ptrCount, S.leafBlockPos);
  clock.lap("alloc");

  // ---- scan counts (step 5) -------------------------------------------------------------------
  S.offsets.ensure(impl, sizeof(uint32_t) * n, "pair offsets");
  const uint64_t numPairs =
      scanOnDevice(impl, run, S.tileSums, S.tileOffsets, S.counts, false, S.offsets, n, "pair counts");
  clock.lap("scan");

  // ---- write pairs (step 6) -------------------------------------------------------------------
  const uint32_t m = static_cast<uint32_t>(numPairs);
  for (Buffer* b : {&S.keys, &S.values, &S.tmpKeys, &S.tmpValues}) b->ensure(impl, sizeof(uint32_t) * m, "pairs");
  run.run("mt_write_pairs", n, 0, S.pts, S.tris, n, S.params, leafDesc, S.leafPtr, exactArg, S.offsets, S.masks,
          S.keys, S.values);
  clock.lap("pairs");

  // ---- stable radix sort by leaf (step 7) -----------------------------------------------------
  Buffer *keys = &S.keys, *values = &S.values, *outKeys = &S.tmpKeys, *outValues = &S.tmpValues;
  if (m > 1) {
    const uint64_t maxKey = numBlocks * leafDesc.blockVolume;
    const int keyBits = ceilLog2(std::max<uint64_t>(maxKey, 2));
    const uint32_t tiles = tilesOf(m, impl.wg);
    const uint32_t histSize = 16 * tiles;
    S.hist.ensure(impl, sizeof(uint32_t) * histSize, "radix histogram");
    S.histScan.ensure(impl, sizeof(uint32_t) * histSize, "radix histogram scan");
    for (int shift = 0; shift < keyBits; shift += 4) {
      run.run("mt_radix_hist", size_t(tiles) * impl.wg, size_t(impl.wg), *keys, m, cl_int(shift), S.hist);
      scanOnDevice(impl, run, S.tileSums, S.tileOffsets, S.hist, false, S.histScan, histSize, "radix histogram");
      run.run("mt_radix_scatter", size_t(tiles) * impl.wg, size_t(impl.wg), *keys, *values, m, cl_int(shift),
              S.histScan, *outKeys, *outValues);
      std::swap(keys, outKeys);
      std::swap(values, outValues);
    }
  }
  clock.lap("sort");

  // ---- leaf ranges from neighbouring keys (step 8) --------------------------------------------
  const uint64_t leafEntries = numBlocks * leafDesc.blockVolume;
  S.leafData.ensure(impl, sizeof(MtLeafRange) * leafEntries, "leaf ranges");
  const MtLeafRange nullRange{MT_NULL, MT_NULL};
  run.fill(S.leafData, &nullRange, sizeof nullRange, sizeof(MtLeafRange) * leafEntries, "leaf ranges");
  S.leafCount.ensure(impl, sizeof(uint32_t), "leaf count");
  const uint32_t zero32 = 0;
  run.fill(S.leafCount, &zero32, sizeof zero32, sizeof zero32, "leaf count");
  run.run("mt_leaf_offsets", m, 0, *keys, m, S.leafData, S.leafCount);
  clock.lap("offsets");

  // ---- existence up to the root (step 9) ------------------------------------------------------
  std::vector<BlockSparseMatrix<uint8_t>>& inner = Access::inner(tree);
  inner.resize(H);
  if (S.levels.size() < static_cast<size_t>(H)) S.levels.resize(H);
  std::vector<uint64_t> levelBlocks(H + 1, 0);
  levelBlocks[H] = numBlocks;
  for (int l = H - 1; l >= 0; --l) {
    const auto& pl = logDims[l];
    const auto& cl = logDims[l + 1];
    const cl_int sh0 = cl[0] - pl[0], sh1 = cl[1] - pl[1], sh2 = cl[2] - pl[2];
    BlockSparseMatrix<uint8_t>& parent = inner[l];
    parent.reset(1 << pl[0], 1 << pl[1], 1 << pl[2], opt.blockEdge, 0);
    const MtSparseDesc pd = parent.desc();
    const MtSparseDesc cd = (l + 1 == H) ? leafDesc : inner[l + 1].desc();
    const uint32_t pcount = static_cast<uint32_t>(parent.pointerCount());
    const uint32_t ccount = cd.ptrDims[0] * cd.ptrDims[1] * cd.ptrDims[2];
    State::Level& P = S.levels[l];
    const Buffer& cptr = (l + 1 == H) ? S.leafPtr : S.levels[l + 1].ptr;
    const Buffer& cpos = (l + 1 == H) ? S.leafBlockPos : S.levels[l + 1].blockPos;
    P.marks.ensure(impl, pcount, "level block marks");
    run.fill(P.marks, &zero8, 1, pcount, "level block marks");
    run.run("mt_parent_mark", ccount, 0, cptr, cd, pd, sh0, sh1, sh2, P.marks);
    P.ptr.ensure(impl, sizeof(uint32_t) * pcount, "level pointers");
    const uint64_t pblocks =
        scanOnDevice(impl, run, S.tileSums, S.tileOffsets, P.marks, true, P.ptr, pcount, "level block marks");
    levelBlocks[l] = pblocks;
    P.blockPos.ensure(impl, sizeof(uint32_t) * pblocks, "level block positions");
    run.run("mt_finish_alloc", pcount, 0, P.marks, P.ptr, pcount, P.blockPos);
    const uint64_t pentries = pblocks * pd.blockVolume;
    P.data.ensure(impl, pentries, "level existence");
    run.fill(P.data, &zero8, 1, pentries, "level existence");
    const uint32_t nce = static_cast<uint32_t>(levelBlocks[l + 1] * cd.blockVolume);
    const cl_int childIsLeaf = (l + 1 == H) ? 1 : 0;
    const Buffer& innerChild = (l + 1 == H) ? P.data /* unused */ : S.levels[l + 1].data;
    run.run("mt_parent_scatter", nce, 0, childIsLeaf, S.leafData, innerChild, nce, cd, cpos, pd, P.ptr, sh0, sh1, sh2,
            P.data);
  }
  clock.lap("propagate");

  // ---- copy into the host tree ----------------------------------------------------------------
  {
    std::vector<uint8_t> marks(ptrCount);
    run.read(S.marks, marks.data(), ptrCount, "leaf block marks");
    leaves.allocateMarked(marks.data(), threads);
    run.read(S.leafData, leaves.data().data(), sizeof(MtLeafRange) * leafEntries, "leaf ranges");
    LargeVector<uint32_t>& prims = Access::prims(tree);
    prims.resize(m);
    run.read(*values, prims.data(), sizeof(uint32_t) * m, "triangle indices");
    uint32_t leafCount = 0;
    run.read(S.leafCount, &leafCount, sizeof leafCount, "leaf count");
    if (stats) stats->leaves = leafCount;
    if (S.keepPointers) {
      S.devicePointers.assign(H + 1, {});
      S.devicePointers[H].resize(ptrCount);
      run.read(S.leafPtr, S.devicePointers[H].data(), sizeof(uint32_t) * ptrCount, "leaf pointers");
    }
    for (int l = 0; l < H; ++l) {
      BlockSparseMatrix<uint8_t>& mat = inner[l];
      std::vector<uint8_t> pm(mat.pointerCount());
      run.read(S.levels[l].marks, pm.data(), pm.size(), "level block marks");
      mat.allocateMarked(pm.data(), threads);
      run.read(S.levels[l].data, mat.data().data(), mat.data().size(), "level existence");
      if (S.keepPointers) {
        S.devicePointers[l].resize(pm.size());
        run.read(S.levels[l].ptr, S.devicePointers[l].data(), sizeof(uint32_t) * pm.size(), "level pointers");
      }
    }
  }
  Access::root(tree) = root;
  Access::height(tree) = H;
  Access::logDims(tree) = logDims;
  Access::cellSize(tree) = cellSize;
  Access::invLeaf(tree) = invLeaf;
  Access::empty(tree) = false;
  if (stats) stats->references = numPairs;
  clock.lap("download");
  tree.buildWalkCaches(0);
  clock.lap("walk caches");
  clock.finish();
}

}  // namespace ocl
}  // namespace mtree

#endif  // MATRIXTREE_HAVE_OPENCL
