// The hybrid matrix/SAH tree: the matrix build, then a binned SAH kd-tree per large leaf. See
// hybrid_tree.h.
#include "mtree/trees/hybrid_tree.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "mtree/core/parallel.h"
#include "plane_sweep.h"

namespace mtree {

namespace {

double halfArea(const Box& b) {
  const Vec3 e = b.extent();
  return e.x * e.y + e.y * e.z + e.z * e.x;
}

struct Entry {
  uint32_t id;
  Box b;  // the triangle's box clipped to the node's box
};

/// One matrix leaf's kd-tree, built into local arrays (child and triangle indices local too).
class LeafKdBuilder {
 public:
  LeafKdBuilder(const HybridBuildOptions& opt, const SplitFrame& f) : opt_(opt), f_(f) {}

  void build(const TriangleMesh& mesh, const uint32_t* ids, uint32_t n, const Box& box) {
    nodes.clear();
    prims.clear();
    depth = 0;
    leaves = 0;
    std::vector<Entry> es(n);
    for (uint32_t i = 0; i < n; ++i) {
      const Box tb = mesh.bounds(ids[i]);
      Box c;
      for (int a = 0; a < 3; ++a) {
        // Clipped to the leaf; a triangle that only grazes it (the builder's padded overlap test)
        // is flattened onto the nearest face.
        c.lo[a] = std::min(std::max(tb.lo[a], box.lo[a]), box.hi[a]);
        c.hi[a] = std::max(std::min(tb.hi[a], box.hi[a]), c.lo[a]);
      }
      es[i] = Entry{ids[i], c};
    }
    nodes.resize(1);
    node(0, box, es, 0);
  }

  std::vector<SahKdNode> nodes;
  std::vector<uint32_t> prims;
  int depth = 0;
  uint64_t leaves = 0;

 private:
  void node(uint32_t idx, const Box& box, std::vector<Entry>& es, int d) {
    const uint32_t n = static_cast<uint32_t>(es.size());
    const double area = halfArea(box);
    int bestAxis = -1;
    float bestS = 0;
    double bestW = 0, bestCost = opt_.costIntersect * n;
    if (n > 1 && d < opt_.maxDepth && area > 0) {
      for (int a = 0; a < 3; ++a) {
        if (!(box.lo[a] < box.hi[a])) continue;
        auto interval = [&](size_t i, double& lo, double& hi) {
          lo = es[i].b.lo[a];
          hi = es[i].b.hi[a];
        };
        const int even = detail::candidatePositions(n, opt_.bins, box.lo[a], box.hi[a], interval, xs_);
        sweep_.run(f_, a, xs_, box.lo[a], box.hi[a], n, interval, even, box.lo[a], box.hi[a]);
        const int a1 = (a + 1) % 3, a2 = (a + 2) % 3;
        const double e1 = box.hi[a1] - box.lo[a1], e2 = box.hi[a2] - box.lo[a2];
        for (size_t j = 0; j < sweep_.w.size(); ++j) {
          const double wl = sweep_.w[j] - box.lo[a], wr = box.hi[a] - sweep_.w[j];
          const double al = wl * (e1 + e2) + e1 * e2, ar = wr * (e1 + e2) + e1 * e2;
          const uint32_t nl = sweep_.nl[j], nr = sweep_.nr[j];
          double c = opt_.costTraverse + opt_.costIntersect * (al * nl + ar * nr) / area;
          if (nl == 0 || nr == 0) c *= opt_.emptyBonus;
          if (c < bestCost) {
            bestCost = c;
            bestAxis = a;
            bestS = sweep_.s[j];
            bestW = sweep_.w[j];
          }
        }
      }
    }
    if (bestAxis < 0) {
      std::vector<uint32_t> ids(n);
      for (uint32_t i = 0; i < n; ++i) ids[i] = es[i].id;
      std::sort(ids.begin(), ids.end());
      nodes[idx] = SahKdNode::leaf(n, static_cast<uint32_t>(prims.size()));
      prims.insert(prims.end(), ids.begin(), ids.end());
      ++leaves;
      depth = std::max(depth, d);
      return;
    }
    const int a = bestAxis;
    Box lbox = box, rbox = box;
    lbox.hi[a] = bestW;
    rbox.lo[a] = bestW;
    std::vector<Entry> left, right;
    for (const Entry& e : es) {
      if (e.b.lo[a] <= bestW) {
        Entry l = e;
        l.b.hi[a] = std::min(l.b.hi[a], bestW);
        left.push_back(l);
      }
      if (e.b.hi[a] >= bestW) {
        Entry r = e;
        r.b.lo[a] = std::max(r.b.lo[a], bestW);
        right.push_back(r);
      }
    }
    es.clear();
    es.shrink_to_fit();
    const uint32_t c = static_cast<uint32_t>(nodes.size());
    nodes.resize(c + 2);
    nodes[idx] = SahKdNode::inner(a, bestS, c);
    node(c, lbox, left, d + 1);
    node(c + 1, rbox, right, d + 1);
  }

  const HybridBuildOptions& opt_;
  const SplitFrame& f_;
  detail::PlaneSweep sweep_;
  std::vector<double> xs_;
};

}  // namespace

void HybridTree::build(const TriangleMesh& mesh, const HybridBuildOptions& opt, HybridBuildStats* stats) {
  if (opt.leafTriangles < 1) throw std::invalid_argument("HybridTree: leafTriangles must be >= 1");
  if (opt.bins < 2 || opt.bins > 64) throw std::invalid_argument("HybridTree: bins must be in [2, 64]");
  if (opt.maxDepth < 1 || opt.maxDepth > kMaxDepth)
    throw std::invalid_argument("HybridTree: maxDepth must be in [1, " + std::to_string(kMaxDepth) + "]");
  if (!(opt.costTraverse >= 0) || !(opt.costIntersect > 0) || !(opt.emptyBonus > 0))
    throw std::invalid_argument("HybridTree: costs must be positive");
  const auto t0 = std::chrono::steady_clock::now();
  HybridBuildStats st;
  nodes_.clear();
  prims_.clear();
  MatrixTreeBuilder<TriangleMesh>::build(mesh, opt.matrix, matrix_, &st.matrix);
  const auto t1 = std::chrono::steady_clock::now();
  st.matrixMs = std::chrono::duration<double, std::milli>(t1 - t0).count();
  roots_ = BlockSparseMatrix<uint32_t>();
  if (!matrix_.empty()) {
    const Box& root = matrix_.rootBox();
    double ext = 0;
    for (int a = 0; a < 3; ++a) ext = std::max(ext, root.hi[a] - root.lo[a]);
    int e = 0;
    std::frexp(std::max(ext, 1e-300), &e);  // 2^e >= ext
    const double anchor[3] = {root.lo.x, root.lo.y, root.lo.z};
    frame_ = SplitFrame::axes(anchor, std::ldexp(1.0, e + 2), 0.0);
    const int H = matrix_.height();
    roots_.reset(matrix_.dim(H, 0), matrix_.dim(H, 1), matrix_.dim(H, 2), matrix_.blockEdge(), MT_NULL);
    // The leaves that get a kd-tree, with their positions.
    const BlockSparseMatrix<MtLeafRange>& lv = matrix_.leafLevel();
    struct Job {
      int c[3];
      MtLeafRange r;
    };
    std::vector<Job> jobs;
    for (uint32_t s = 0; s < lv.data().size(); ++s) {
      const MtLeafRange& r = lv.data()[s];
      if (r.begin == MT_NULL) continue;
      if (r.end - r.begin <= uint32_t(opt.leafTriangles)) {
        ++st.leavesTested;
        continue;
      }
      Job j;
      lv.entryCoords(s, j.c);
      j.r = r;
      jobs.push_back(j);
    }
    // Built in parallel into per-job arrays, then appended in job order (a deterministic tree).
    std::vector<std::vector<SahKdNode>> jn(jobs.size());
    std::vector<std::vector<uint32_t>> jp(jobs.size());
    std::vector<int> jd(jobs.size());
    std::vector<uint64_t> jl(jobs.size());
    const int threads = resolveThreads(opt.matrix.threads);
    const uint32_t* ids = matrix_.primitiveIndices().data();
#pragma omp parallel num_threads(threads)
    {
      LeafKdBuilder b(opt, frame_);
#pragma omp for schedule(dynamic, 16)
      for (int64_t i = 0; i < static_cast<int64_t>(jobs.size()); ++i) {
        const Job& j = jobs[i];
        b.build(mesh, ids + j.r.begin, j.r.end - j.r.begin, matrix_.nodeBox(H, j.c));
        jn[i] = std::move(b.nodes);
        jp[i] = std::move(b.prims);
        jd[i] = b.depth;
        jl[i] = b.leaves;
      }
    }
    for (size_t i = 0; i < jobs.size(); ++i) {
      const uint32_t nodeBase = static_cast<uint32_t>(nodes_.size()), primBase = static_cast<uint32_t>(prims_.size());
      if (nodes_.size() + jn[i].size() > SahKdTree::kMaxIndex || prims_.size() + jp[i].size() > SahKdTree::kMaxIndex)
        throw std::length_error("HybridTree: more than 2^30 kd nodes or references");
      for (const SahKdNode& nd : jn[i])
        nodes_.push_back(nd.isLeaf() ? SahKdNode::leaf(nd.primCount(), nd.primOffset() + primBase)
                                     : SahKdNode::inner(nd.axis(), nd.split(), nd.leftChild() + nodeBase));
      prims_.insert(prims_.end(), jp[i].begin(), jp[i].end());
      roots_.insert(jobs[i].c[0], jobs[i].c[1], jobs[i].c[2]) = nodeBase;
      st.kdDepth = std::max(st.kdDepth, jd[i]);
      st.kdLeaves += jl[i];
    }
    st.subtrees = jobs.size();
    st.kdNodes = nodes_.size();
    st.kdReferences = prims_.size();
  }
  const auto t2 = std::chrono::steady_clock::now();
  st.subtreeMs = std::chrono::duration<double, std::milli>(t2 - t1).count();
  st.totalMs = std::chrono::duration<double, std::milli>(t2 - t0).count();
  if (stats) *stats = st;
}

std::vector<SplitPolygon> HybridTree::splitPolygons(int maxLevel) const {
  std::vector<SplitPolygon> out;
  if (matrix_.empty()) return out;
  const int H = matrix_.height();
  const BlockSparseMatrix<MtLeafRange>& lv = matrix_.leafLevel();
  struct Item {
    uint32_t node;
    Box box;
    int level;
  };
  for (uint32_t s = 0; s < lv.data().size(); ++s) {
    if (lv.data()[s].begin == MT_NULL) continue;
    int c[3];
    lv.entryCoords(s, c);
    const uint32_t root = roots_.get(c[0], c[1], c[2]);
    if (root == MT_NULL) continue;
    std::vector<Item> stack{{root, matrix_.nodeBox(H, c), 0}};
    while (!stack.empty()) {
      const Item it = stack.back();
      stack.pop_back();
      const SahKdNode& nd = nodes_[it.node];
      if (nd.isLeaf() || it.level > maxLevel) continue;
      const int a = nd.axis(), a1 = (a + 1) % 3, a2 = (a + 2) % 3;
      const double w = frame_.world(a, nd.split());
      SplitPolygon p;
      p.level = it.level;
      p.dir = a;
      for (int k = 0; k < 4; ++k) {
        Vec3 q;
        q[a] = w;
        q[a1] = (k == 1 || k == 2) ? it.box.hi[a1] : it.box.lo[a1];
        q[a2] = k >= 2 ? it.box.hi[a2] : it.box.lo[a2];
        p.points.push_back(q);
      }
      out.push_back(std::move(p));
      Box l = it.box, r = it.box;
      l.hi[a] = w;
      r.lo[a] = w;
      stack.push_back({nd.leftChild(), l, it.level + 1});
      stack.push_back({nd.leftChild() + 1, r, it.level + 1});
    }
  }
  return out;
}

}  // namespace mtree
