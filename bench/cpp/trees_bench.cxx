// trees_bench: the paper's §4 and §7 structures on one scene, one thread, CPU clock
// (bench/trees.py writes the scene file, runs this program and prints the tables).
//
//   trees_bench SCENE.bin OUT.json [--samples S] [--blocks 0,1,2,4,8,16,32] [--render-blocks 0,8]
//               [--depths 8,12,16,20,24] [--bsp-bonus B] [--bsp-bins N] [--hybrid-scales 4,8]
//               [--hybrid-depths 8] [--skip-bsp] [--opencl] [--device SEL] [--planes DIR]
//               [--plane-levels L]
//
// Per scene (the first frame of the file):
//  storage  node bytes of the implicit kd-tree built from the SAH tree (same splits), per layout:
//           the block shape chosen per level (block 0) and B^3 blocks on every level, against the
//           pointer SAH tree's 8 bytes a node, and the same for a complete kd-tree (median splits,
//           4 triangles a leaf: every level full, the layout's best case); per level of the per-level layout: nodes, block
//           shape, fill, bytes (and the same level's bytes with 8^3 blocks); the same for the BSP.
//  depths   SAH trees built with lower depth limits: pointer and implicit bytes, SAH cost, and the
//           render of both (where "half the storage" holds: shallow trees).
//  render   one render (primary rays + one shadow ray per hit, render.h) per tree and traversal,
//           one OpenMP thread, CPU time of the process: the matrix octree and kd-tree; the pointer
//           SAH tree (stack, restart); the implicit kd-tree (stack, restart, backtrack) per layout
//           of --render-blocks; the implicit BSP tree (13 directions: stack, restart, backtrack;
//           3 directions from the same builder: backtrack); the hybrid per leaf scale and kd depth.
//           Build time (CPU) of each, the implicit trees' = their source tree's build plus the
//           conversion (given apart as convert_cpu_ms; for the hybrid, the kd part: its build less
//           a build of its matrix part alone). Node visits, triangle tests and leaves per ray. Mismatches:
//           S seeded pixels' primary hits against the brute force.
//  opencl   with --opencl: the implicit kd-tree's and BSP tree's stackless kernel on the device,
//           same rays (renderOpenCL), pixels whose hit (triangle, t bit for bit) or colour (the
//           shadow rays) differ from the CPU backtrack render; wall time (the device's threads are
//           not this thread).
//  planes   with --planes DIR: the split planes of levels <= L (default 8) within their cells, of the
//           implicit kd-tree, the BSP tree and the hybrid's kd-trees (with the hybrid's occupied
//           matrix leaves), as legacy VTK files DIR/{kd,bsp,hybrid}_planes.vtk, hybrid_leaves.vtk.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "bench_scene.h"
#include "mtree/core/builder.h"
#include "mtree/device/opencl_render.h"
#include "mtree/device/opencl_trees.h"
#include "mtree/rays/render.h"
#include "mtree/rays/sah_kdtree.h"
#include "mtree/trees/bsp_builder.h"
#include "mtree/trees/hybrid_tree.h"
#include "mtree/trees/implicit_tree.h"

namespace {

using namespace mtree;
using mtbench::cpuMs;

std::vector<int> intList(const std::string& s) {
  std::vector<int> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) v.push_back(std::stoi(item));
  return v;
}
std::vector<double> doubleList(const std::string& s) {
  std::vector<double> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) v.push_back(std::stod(item));
  return v;
}

/// A JSON object written field by field.
class Obj {
 public:
  Obj& num(const std::string& k, double v) {
    sep();
    o_ << "\"" << k << "\": ";
    if (std::isfinite(v))
      o_ << v;
    else
      o_ << "null";
    return *this;
  }
  Obj& str(const std::string& k, const std::string& v) {
    sep();
    o_ << "\"" << k << "\": \"" << v << "\"";
    return *this;
  }
  Obj& raw(const std::string& k, const std::string& v) {
    sep();
    o_ << "\"" << k << "\": " << v;
    return *this;
  }
  std::string done() const { return "{" + o_.str() + "}"; }
  Obj() { o_.precision(10); }

 private:
  void sep() {
    if (!first_) o_ << ", ";
    first_ = false;
  }
  std::ostringstream o_;
  bool first_ = true;
};

std::string array(const std::vector<std::string>& items, const char* indent = "    ") {
  std::string s = "[\n";
  for (size_t i = 0; i < items.size(); ++i) s += indent + items[i] + (i + 1 < items.size() ? ",\n" : "\n");
  return s + "  ]";
}

struct RenderRow {
  std::string method, traversal, layout;
  double buildCpuMs = 0, convertCpuMs = 0, renderCpuMs = 0;
  RenderResult r;
  uint64_t mismatches = 0, checked = 0;
  size_t bytes = 0;
  uint64_t nodes = 0;
  std::string json() const {
    const double rays = double(r.primaryRays + r.shadowRays);
    return Obj()
        .str("method", method)
        .str("traversal", traversal)
        .str("layout", layout)
        .num("build_cpu_ms", buildCpuMs)
        .num("convert_cpu_ms", convertCpuMs)
        .num("render_cpu_ms", renderCpuMs)
        .num("rays", rays)
        .num("node_visits_per_ray", rays > 0 ? double(r.stats.nodeVisits) / rays : 0)
        .num("tri_tests_per_ray", rays > 0 ? double(r.stats.primTests) / rays : 0)
        .num("leaves_per_ray", rays > 0 ? double(r.stats.cells) / rays : 0)
        .num("mismatches_vs_brute_force", double(mismatches))
        .num("rays_checked", double(checked))
        .num("bytes", double(bytes))
        .num("nodes", double(nodes))
        .done();
  }
};

std::string levelJson(int l, const ImplicitLevelCost& c, const ImplicitLevelCost& b8) {
  return Obj()
      .num("level", l)
      .num("nodes", double(c.nodes))
      .num("empty_leaves", double(c.emptyLeaves))
      .raw("log_block", "[" + std::to_string(c.logBlock[0]) + ", " + std::to_string(c.logBlock[1]) + ", " +
                            std::to_string(c.logBlock[2]) + "]")
      .num("pointers", double(c.pointers))
      .num("blocks", double(c.blocks))
      .num("fill", c.fill())
      .num("bytes", double(c.bytes))
      .num("bytes_b8", double(b8.bytes))
      .num("fill_b8", b8.fill())
      .num("pointer_tree_bytes", 8.0 * double(c.nodes + c.emptyLeaves))
      .done();
}

/// Storage rows of a pointer tree `p` for each block edge: node bytes against 8 bytes a node.
std::vector<std::string> storageRows(const std::string& tree, const PointerSplitTree& p, const std::vector<int>& blocks) {
  std::vector<std::string> rows;
  const double nodes = double(p.nodes.size());
  const double ptrNodeBytes = 8.0 * nodes, refBytes = 4.0 * double(p.prims.size());
  for (int B : blocks) {
    const ImplicitLayoutCost c = ImplicitSplitTree::layoutCost(p, B);
    const double nb = double(c.nodeBytes());
    rows.push_back(Obj()
                       .str("tree", tree)
                       .str("layout", B == 0 ? "per-level" : std::to_string(B) + "^3")
                       .num("block_edge", B)
                       .num("nodes", nodes)
                       .num("levels", double(c.levels.size()))
                       .num("implicit_node_bytes", nb)
                       .num("implicit_bytes_per_node", nb / nodes)
                       .num("implicit_total_bytes", nb + refBytes)
                       .num("pointer_node_bytes", ptrNodeBytes)
                       .num("pointer_total_bytes", ptrNodeBytes + refBytes)
                       .num("node_bytes_ratio", nb / ptrNodeBytes)
                       .done());
  }
  return rows;
}

/// Polygons as a legacy VTK polydata file with cell data "level" and "direction" (the pictures).
void writePolygons(const std::string& path, const std::vector<SplitPolygon>& polys) {
  std::ofstream f(path);
  size_t np = 0, conn = 0;
  for (const auto& p : polys) {
    np += p.points.size();
    conn += p.points.size() + 1;
  }
  f.precision(17);
  f << "# vtk DataFile Version 3.0\nsplit planes\nASCII\nDATASET POLYDATA\nPOINTS " << np << " double\n";
  for (const auto& p : polys)
    for (const Vec3& q : p.points) f << q.x << " " << q.y << " " << q.z << "\n";
  f << "POLYGONS " << polys.size() << " " << conn << "\n";
  size_t at = 0;
  for (const auto& p : polys) {
    f << p.points.size();
    for (size_t i = 0; i < p.points.size(); ++i) f << " " << at++;
    f << "\n";
  }
  f << "CELL_DATA " << polys.size() << "\nSCALARS level int 1\nLOOKUP_TABLE default\n";
  for (const auto& p : polys) f << p.level << "\n";
  f << "SCALARS direction int 1\nLOOKUP_TABLE default\n";
  for (const auto& p : polys) f << p.dir << "\n";
  if (!f) throw std::runtime_error("cannot write " + path);
}

/// The occupied leaves of a matrix tree as boxes (6 quads each), level = the tree height.
std::vector<SplitPolygon> leafBoxes(const MatrixTree& t) {
  std::vector<SplitPolygon> out;
  const int H = t.height();
  const auto& lv = t.leafLevel();
  for (uint32_t s = 0; s < lv.data().size(); ++s) {
    if (lv.data()[s].begin == MT_NULL) continue;
    int c[3];
    lv.entryCoords(s, c);
    const Box b = t.nodeBox(H, c);
    for (int a = 0; a < 3; ++a)
      for (int side = 0; side < 2; ++side) {
        SplitPolygon p;
        p.level = H;
        p.dir = a;
        const int a1 = (a + 1) % 3, a2 = (a + 2) % 3;
        for (int k = 0; k < 4; ++k) {
          Vec3 q;
          q[a] = side ? b.hi[a] : b.lo[a];
          q[a1] = (k == 1 || k == 2) ? b.hi[a1] : b.lo[a1];
          q[a2] = k >= 2 ? b.hi[a2] : b.lo[a2];
          p.points.push_back(q);
        }
        out.push_back(std::move(p));
      }
  }
  return out;
}

/// A complete kd-tree (the best case of the implicit layout: every level full): median splits of
/// the triangles' centroids on the longest axis of their bounds, down to `leafSize` triangles;
/// each triangle goes to the side of its centroid. For the storage table only: it is not a tree
/// a ray could be traced through (a triangle can reach the other side).
PointerSplitTree medianTree(const TriangleMesh& mesh, uint32_t leafSize) {
  PointerSplitTree p;
  if (mesh.size() == 0) return p;
  Box box;
  std::vector<Vec3> cent(mesh.size());
  for (size_t t = 0; t < mesh.size(); ++t) {
    box.extend(mesh.bounds(t));
    cent[t] = (mesh.vertex(t, 0) + mesh.vertex(t, 1) + mesh.vertex(t, 2)) * (1.0 / 3.0);
  }
  const double anchor[3] = {box.lo.x, box.lo.y, box.lo.z};
  int e = 0;
  std::frexp(std::max(box.extent().x, std::max(box.extent().y, box.extent().z)), &e);
  p.frame = SplitFrame::axes(anchor, std::ldexp(1.0, e + 2), SplitFrame::padUnitOf(box));
  p.root = box;
  std::vector<uint32_t> ids(mesh.size());
  for (uint32_t t = 0; t < ids.size(); ++t) ids[t] = t;
  p.nodes.resize(1);
  std::function<void(uint32_t, size_t, size_t)> node = [&](uint32_t idx, size_t b, size_t n) {
    if (n <= leafSize) {
      p.nodes[idx].leaf = true;
      p.nodes[idx].offset = static_cast<uint32_t>(b);
      p.nodes[idx].count = static_cast<uint32_t>(n);
      return;
    }
    Box cb;
    for (size_t i = b; i < b + n; ++i) cb.extend(cent[ids[i]]);
    const Vec3 ext = cb.extent();
    const int a = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const size_t m = n / 2;
    std::nth_element(ids.begin() + b, ids.begin() + b + m, ids.begin() + b + n,
                     [&](uint32_t x, uint32_t y) { return cent[x][a] < cent[y][a]; });
    const uint32_t c = static_cast<uint32_t>(p.nodes.size());
    p.nodes.resize(c + 2);
    p.nodes[idx].leaf = false;
    p.nodes[idx].dir = static_cast<uint8_t>(a);
    p.nodes[idx].s = p.frame.toFloat(a, cent[ids[b + m]][a]);
    p.nodes[idx].child = c;
    node(c, b, m);
    node(c + 1, b + m, n - m);
  };
  node(0, 0, ids.size());
  p.prims = ids;
  return p;
}

int run(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: trees_bench SCENE.bin OUT.json [--samples S] [--blocks 0,1,2,4,8,16,32] [--render-blocks 0]\n"
                 "       [--depths 8,12,16,20,24] [--bsp-bonus B] [--bsp-bins N] [--hybrid-scales 4,8]\n"
                 "       [--hybrid-depths 8] [--skip-bsp] [--opencl] [--device SEL] [--planes DIR] [--plane-levels L]\n");
    return 2;
  }
  const std::string scenePath = argv[1], outPath = argv[2];
  int samples = 2000;
  std::vector<int> blocks = {0, 1, 2, 4, 8, 16, 32}, renderBlocks = {0}, depths = {8, 12, 16, 20, 24};
  std::vector<int> hybridDepths = {8};
  std::vector<double> hybridScales = {4, 8};
  BspBuildOptions bspOpt;
  bool skipBsp = false, useCl = false;
  std::string deviceSel, planesDir;
  int planeLevels = 8;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(a + " needs a value");
      return argv[++i];
    };
    if (a == "--samples") samples = std::max(0, std::stoi(next()));
    else if (a == "--blocks") blocks = intList(next());
    else if (a == "--render-blocks") renderBlocks = intList(next());
    else if (a == "--depths") depths = intList(next());
    else if (a == "--bsp-bonus") bspOpt.emptyBonus = std::stod(next());
    else if (a == "--bsp-bins") bspOpt.bins = std::stoi(next());
    else if (a == "--hybrid-scales") hybridScales = doubleList(next());
    else if (a == "--hybrid-depths") hybridDepths = intList(next());
    else if (a == "--skip-bsp") skipBsp = true;
    else if (a == "--opencl") useCl = true;
    else if (a == "--device") deviceSel = next();
    else if (a == "--planes") planesDir = next();
    else if (a == "--plane-levels") planeLevels = std::stoi(next());
    else throw std::runtime_error("unknown option " + a);
  }
  const mtbench::Scene sc = mtbench::readScene(scenePath);
  const TriangleMesh mesh(sc.frames[0], sc.tris);
  Box box;
  for (size_t i = 0; i + 2 < sc.frames[0].size(); i += 3)
    box.extend(Vec3(sc.frames[0][i], sc.frames[0][i + 1], sc.frames[0][i + 2]));
  std::fprintf(stderr, "trees_bench: %u triangles, %dx%d, one thread\n", sc.nt, sc.cam.width, sc.cam.height);
  const std::vector<mtbench::Sample> ref = mtbench::referenceHits(mesh, sc.cam, samples, 0x5EEDull);
  RenderOptions ropt;
  ropt.threads = 1;
  std::vector<RenderRow> rows;
  std::vector<std::string> storage, levels, bspLevels, depthRows, clRows;

  auto renderRow = [&](RenderRow row, const auto& tracer) {
    const double c0 = cpuMs();
    row.r = render(tracer, mesh, box, sc.cam, ropt);
    row.renderCpuMs = cpuMs() - c0;
    row.mismatches = mtbench::countMismatches(row.r, ref);
    row.checked = ref.size();
    std::fprintf(stderr, "  %-14s %-10s %-10s build %9.1f ms  render %8.1f ms  mismatches %llu\n", row.method.c_str(),
                 row.traversal.c_str(), row.layout.c_str(), row.buildCpuMs, row.renderCpuMs,
                 (unsigned long long)row.mismatches);
    rows.push_back(row);
    return rows.back().r;
  };

  // ---- matrix trees ----
  for (TreeKind kind : {TreeKind::Octree, TreeKind::RegularKd}) {
    BuildOptions bo;
    bo.kind = kind;
    bo.threads = 1;
    MatrixTree t;
    BuildStats bs;
    const double c0 = cpuMs();
    MatrixTreeBuilder<TriangleMesh>::build(mesh, bo, t, &bs);
    RenderRow row;
    row.method = kind == TreeKind::Octree ? "matrix-octree" : "matrix-kdtree";
    row.traversal = "matrix";
    row.buildCpuMs = cpuMs() - c0;
    row.bytes = t.bytes();
    row.nodes = bs.leaves;
    renderRow(row, MatrixTreeTracer{t, mesh});
  }

  // ---- SAH tree and the implicit kd-tree with its splits ----
  double c0 = cpuMs();
  SahKdTree sah(mesh);
  const double sahMs = cpuMs() - c0;
  const PointerSplitTree sahPtr = pointerTreeOf(sah);
  for (SahTraversal tr : {SahTraversal::Stack, SahTraversal::Restart}) {
    RenderRow row;
    row.method = "sah-pointer";
    row.traversal = sahTraversalName(tr);
    row.layout = "pointer";
    row.buildCpuMs = sahMs;
    row.bytes = sah.bytes();
    row.nodes = sah.stats().nodes;
    renderRow(row, SahTracer{sah, mesh, tr});
  }
  storage = storageRows("kd", sahPtr, blocks);
  for (const std::string& r : storageRows("kd-complete", medianTree(mesh, 4), blocks)) storage.push_back(r);
  std::unique_ptr<ImplicitSplitTree> kdPerLevel;
  RenderResult kdBacktrackRender;
  for (int B : renderBlocks) {
    auto tree = std::make_unique<ImplicitSplitTree>();
    c0 = cpuMs();
    try {
      tree->build(sahPtr, mesh, B);
    } catch (const std::length_error& e) {
      std::fprintf(stderr, "  implicit kd, block edge %d: %s (not rendered)\n", B, e.what());
      continue;
    }
    const double convMs = cpuMs() - c0;
    for (SplitTraversal tr : {SplitTraversal::Stack, SplitTraversal::Restart, SplitTraversal::Backtrack}) {
      RenderRow row;
      row.method = "implicit-kd";
      row.traversal = splitTraversalName(tr);
      row.layout = B == 0 ? "per-level" : std::to_string(B) + "^3";
      row.buildCpuMs = sahMs + convMs;
      row.convertCpuMs = convMs;
      row.bytes = tree->bytes();
      row.nodes = tree->numNodes();
      const RenderResult& r = renderRow(row, ImplicitTreeTracer{*tree, mesh, tr});
      if (B == 0 && tr == SplitTraversal::Backtrack) kdBacktrackRender = r;
    }
    if (B == 0) kdPerLevel = std::move(tree);
  }
  if (!planesDir.empty() && kdPerLevel) writePolygons(planesDir + "/kd_planes.vtk", kdPerLevel->splitPolygons(planeLevels));
  {
    const ImplicitLayoutCost per = ImplicitSplitTree::layoutCost(sahPtr, 0), b8 = ImplicitSplitTree::layoutCost(sahPtr, 8);
    for (size_t l = 0; l < per.levels.size(); ++l) levels.push_back(levelJson(int(l), per.levels[l], b8.levels[l]));
  }

  // ---- depth limits: where the implicit encoding pays ----
  for (int dl : depths) {
    SahBuildOptions so;
    so.maxDepth = dl;
    const SahKdTree s(mesh, so);
    const PointerSplitTree p = pointerTreeOf(s);
    ImplicitSplitTree t;
    t.build(p, mesh, 0);
    const double ptrNodes = 8.0 * double(s.stats().nodes);
    RenderResult rp, ri;
    c0 = cpuMs();
    rp = render(SahTracer{s, mesh, SahTraversal::Stack}, mesh, box, sc.cam, ropt);
    const double msP = cpuMs() - c0;
    c0 = cpuMs();
    ri = render(ImplicitTreeTracer{t, mesh, SplitTraversal::Backtrack}, mesh, box, sc.cam, ropt);
    const double msI = cpuMs() - c0;
    depthRows.push_back(Obj()
                            .num("max_depth", dl)
                            .num("depth", s.stats().depth)
                            .num("nodes", double(s.stats().nodes))
                            .num("sah_cost", s.stats().sahCost)
                            .num("pointer_node_bytes", ptrNodes)
                            .num("implicit_node_bytes", double(t.nodeBytes()))
                            .num("node_bytes_ratio", double(t.nodeBytes()) / ptrNodes)
                            .num("references", double(s.stats().references))
                            .num("sah_stack_render_cpu_ms", msP)
                            .num("implicit_backtrack_render_cpu_ms", msI)
                            .num("mismatches_sah", double(mtbench::countMismatches(rp, ref)))
                            .num("mismatches_implicit", double(mtbench::countMismatches(ri, ref)))
                            .done());
    std::fprintf(stderr, "  depth limit %d: pointer %.2f MiB, implicit %.2f MiB, render %.0f / %.0f ms\n", dl,
                 ptrNodes / 1048576.0, t.nodeBytes() / 1048576.0, msP, msI);
  }

  // ---- BSP trees (13 directions; 3 from the same builder) ----
  std::unique_ptr<ImplicitSplitTree> bspTree;
  std::string bspStats = "null";
  if (!skipBsp) {
    for (int dirs : {13, 3}) {
      BspBuildOptions o = bspOpt;
      o.directions = dirs;
      BspBuildStats bs;
      c0 = cpuMs();
      const PointerSplitTree p = buildBspTree(mesh, o, &bs);
      const double buildMs = cpuMs() - c0;
      auto t = std::make_unique<ImplicitSplitTree>();
      c0 = cpuMs();
      t->build(p, mesh, 0);
      const double convMs = cpuMs() - c0;
      const std::string name = dirs == 13 ? "bsp-13" : "bsp-3";
      if (dirs == 13) {
        for (const std::string& s : storageRows(name, p, blocks)) storage.push_back(s);
        const ImplicitLayoutCost per = ImplicitSplitTree::layoutCost(p, 0), b8 = ImplicitSplitTree::layoutCost(p, 8);
        for (size_t l = 0; l < per.levels.size(); ++l)
          bspLevels.push_back(levelJson(int(l), per.levels[l], b8.levels[l]));
        bspStats = Obj()
                       .num("nodes", double(bs.nodes))
                       .num("axis_splits", double(bs.axisSplits))
                       .num("diagonal_splits", double(bs.diagonalSplits))
                       .num("references", double(bs.references))
                       .num("depth", bs.depth)
                       .num("sah_cost", bs.sahCost)
                       .num("empty_bonus", o.emptyBonus)
                       .num("bins", o.bins)
                       .done();
      }
      for (SplitTraversal tr : {SplitTraversal::Stack, SplitTraversal::Restart, SplitTraversal::Backtrack}) {
        if (dirs == 3 && tr != SplitTraversal::Backtrack) continue;
        RenderRow row;
        row.method = name;
        row.traversal = splitTraversalName(tr);
        row.layout = "per-level";
        row.buildCpuMs = buildMs + convMs;
        row.convertCpuMs = convMs;
        row.bytes = t->bytes();
        row.nodes = t->numNodes();
        renderRow(row, ImplicitTreeTracer{*t, mesh, tr});
      }
      if (dirs == 13 && !planesDir.empty()) writePolygons(planesDir + "/bsp_planes.vtk", t->splitPolygons(planeLevels));
      if (dirs == 13) bspTree = std::move(t);
    }
  }

  // ---- hybrid ----
  for (double scale : hybridScales)
    for (int kd : hybridDepths) {
      HybridBuildOptions o;
      o.matrix.threads = 1;
      o.matrix.leafScale = scale;
      o.maxDepth = kd;
      // The matrix part alone, for the kd part's share of the build (CPU clock).
      MatrixTree alone;
      c0 = cpuMs();
      MatrixTreeBuilder<TriangleMesh>::build(mesh, o.matrix, alone, nullptr);
      const double matrixMs = cpuMs() - c0;
      HybridTree h;
      HybridBuildStats hs;
      c0 = cpuMs();
      h.build(mesh, o, &hs);
      RenderRow row;
      row.method = "hybrid";
      row.traversal = "matrix+stack";
      char lay[64];
      std::snprintf(lay, sizeof lay, "leaf%gx-kd%d", scale, kd);
      row.layout = lay;
      row.buildCpuMs = cpuMs() - c0;
      row.convertCpuMs = std::max(0.0, row.buildCpuMs - matrixMs);  // the kd part of the build
      row.bytes = h.bytes();
      row.nodes = hs.kdNodes;
      renderRow(row, HybridTracer{h, mesh});
      if (!planesDir.empty() && scale == hybridScales.front() && kd == hybridDepths.front()) {
        writePolygons(planesDir + "/hybrid_planes.vtk", h.splitPolygons(kd));
        writePolygons(planesDir + "/hybrid_leaves.vtk", leafBoxes(h.matrix()));
      }
    }

  // ---- the stackless kernel on the OpenCL device ----
  std::string clDevice;
  if (useCl) {
    auto ctx = ocl::Context::shared(deviceSel);
    clDevice = ctx->deviceLabel();
    ocl::SplitTreeTracer dev(ctx);
    auto one = [&](const std::string& name, const ImplicitSplitTree& tree) {
      dev.upload(tree, mesh);
      renderOpenCL(dev, mesh, box, sc.cam, ropt);  // untimed: compiles the kernels
      RenderResult cpu = render(ImplicitTreeTracer{tree, mesh, SplitTraversal::Backtrack}, mesh, box, sc.cam, ropt);
      const auto t0 = std::chrono::steady_clock::now();
      const RenderResult g = renderOpenCL(dev, mesh, box, sc.cam, ropt);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      uint64_t hitDiffer = 0, rgbDiffer = 0;
      for (size_t p = 0; p < cpu.hitPrim.size(); ++p) {
        hitDiffer += cpu.hitPrim[p] != g.hitPrim[p] || std::memcmp(&cpu.depth[p], &g.depth[p], sizeof(float)) != 0;
        rgbDiffer += std::memcmp(&cpu.rgb[3 * p], &g.rgb[3 * p], 3) != 0;
      }
      clRows.push_back(Obj()
                           .str("method", name)
                           .str("traversal", "backtrack")
                           .str("device", clDevice)
                           .num("render_wall_ms", ms)
                           .num("pixels", double(cpu.hitPrim.size()))
                           .num("hit_mismatches_vs_cpu", double(hitDiffer))
                           .num("shading_mismatches_vs_cpu", double(rgbDiffer))
                           .num("node_visits_cpu", double(cpu.stats.nodeVisits))
                           .num("node_visits_device", double(g.stats.nodeVisits))
                           .num("tri_tests_cpu", double(cpu.stats.primTests))
                           .num("tri_tests_device", double(g.stats.primTests))
                           .num("mismatches_vs_brute_force", double(mtbench::countMismatches(g, ref)))
                           .done());
      std::fprintf(stderr, "  opencl %s: %.1f ms wall, %llu hits and %llu colours differ from the CPU\n", name.c_str(), ms,
                   (unsigned long long)hitDiffer, (unsigned long long)rgbDiffer);
    };
    if (kdPerLevel) one("implicit-kd", *kdPerLevel);
    if (bspTree) one("bsp-13", *bspTree);
  }

  std::vector<std::string> renderJson;
  for (const RenderRow& r : rows) renderJson.push_back(r.json());
  std::ofstream out(outPath);
  out << "{\n  \"triangles\": " << sc.nt << ",\n  \"width\": " << sc.cam.width << ",\n  \"height\": " << sc.cam.height
      << ",\n  \"threads\": 1,\n  \"clock\": \"CLOCK_PROCESS_CPUTIME_ID\",\n  \"sah\": "
      << Obj()
             .num("nodes", double(sah.stats().nodes))
             .num("depth", sah.stats().depth)
             .num("references", double(sah.stats().references))
             .num("sah_cost", sah.stats().sahCost)
             .num("build_cpu_ms", sahMs)
             .done()
      << ",\n  \"bsp\": " << bspStats << ",\n  \"storage\": " << array(storage) << ",\n  \"levels\": " << array(levels)
      << ",\n  \"bsp_levels\": " << array(bspLevels) << ",\n  \"depths\": " << array(depthRows)
      << ",\n  \"render\": " << array(renderJson) << ",\n  \"opencl\": " << array(clRows) << "\n}\n";
  if (!out) throw std::runtime_error("cannot write " + outPath);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "trees_bench: error: %s\n", e.what());
    return 1;
  }
}
