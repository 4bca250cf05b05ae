// OpenCL host code, part 4: volume ray casting on the device (opencl/volume.cl) over an uploaded
// BlockSparseVolume. The parameters are computed here exactly as renderVolume() computes them
// (engine/src/volume/render.cpp): camera basis, tan of the half angle, the premultiplied table with the
// opacity corrected for the step, the table's float lo/scale; the kernel does the rest per ray.
#ifdef MATRIXTREE_HAVE_OPENCL

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "mtree/core/parallel.h"
#include "opencl_internal.h"

namespace mtree {
namespace ocl {

struct VolumeRenderer::State {
  // ptr/data: the float layout's pointer matrix and DIM^3 blocks, or the apron layout's brick
  // pointers and 9^3 bricks (8 or 16 bits); masks: the apron layout's visible-cell words; dist:
  // the per-octant empty cubes of the bricks (BlockSparseVolume::brickDistances), which the
  // apron float marcher walks by, as marchApron does (the others walk the occupancy levels).
  Buffer ptr, data, masks, occ, dist, params, table, out, counts;
  MtVolumeParams shape{};  // the volume's fields of the kernels' parameters (dims .. level)
  VoxelStorage storage = VoxelStorage::Float32;
  float scale = 1, offset = 0;  // BlockSparseVolume::storageScale/storageOffset (sampleUnits)
  bool uploaded = false;
};

VolumeRenderer::VolumeRenderer(std::shared_ptr<Context> ctx)
    : ctx_(ctx ? std::move(ctx) : Context::shared()), st_(new State) {}
VolumeRenderer::~VolumeRenderer() = default;
Context& VolumeRenderer::context() const { return *ctx_; }
bool VolumeRenderer::uploaded() const { return st_->uploaded; }

void VolumeRenderer::upload(const BlockSparseVolume& vol) {
  if (vol.levelCount() == 0) throw std::invalid_argument("VolumeRenderer (OpenCL): the volume was not built");
  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  State& S = *st_;
  S.uploaded = false;
  const BlockSparseMatrix<float>& m = vol.voxels();
  const MtSparseDesc& d = m.desc();
  S.storage = vol.storage();
  MtVolumeParams& P = S.shape;
  P = MtVolumeParams{};
  S.scale = vol.storageScale();
  S.offset = vol.storageOffset();
  P.offset = S.offset / S.scale;  // sample units, as sampleUnits()
  for (int a = 0; a < 3; ++a) {
    P.dims[a] = vol.dim(a);
    P.logBlock[a] = d.logBlock[a];
  }
  P.ptrDims[0] = d.ptrDims[0];
  P.ptrDims[1] = d.ptrDims[1];
  P.blockVolume = d.blockVolume;
  // The matrix-tree occupancy levels, concatenated (one byte per node, as the CPU keeps them).
  P.levels = vol.levelCount();
  if (P.levels > MT_VOLUME_MAX_LEVELS)
    throw std::length_error("VolumeRenderer (OpenCL): more than " + std::to_string(MT_VOLUME_MAX_LEVELS) +
                            " occupancy levels");
  std::vector<uint8_t> occ;
  for (int L = 0; L < P.levels; ++L) {
    const int nx = vol.levelDim(L, 0), ny = vol.levelDim(L, 1), nz = vol.levelDim(L, 2);
    P.level[L] = MtVolumeLevel{{nx, ny, nz}, static_cast<uint32_t>(occ.size())};
    for (int k = 0; k < nz; ++k)
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) occ.push_back(vol.nodeVisible(L, i, j, k) ? 1 : 0);
  }
  if (occ.size() >= size_t(std::numeric_limits<int32_t>::max()))
    throw std::length_error("VolumeRenderer (OpenCL): occupancy levels too large for 32-bit offsets");
  Launcher run(impl, nullptr);
  auto put = [&](Buffer& b, const void* src, size_t bytes, const char* what) {
    b.ensure(impl, bytes, what);
    run.write(b, src, bytes, what);
  };
  // Each storage is uploaded as the CPU holds it (no conversion), so the device reads the same
  // bits: the float blocks, or the 8/16-bit apron bricks with their cell masks.
  auto putVec = [&](Buffer& b, const auto& v, const char* what) { put(b, v.data(), v.size() * sizeof(v[0]), what); };
  if (S.storage == VoxelStorage::Float32) {
    putVec(S.ptr, m.pointers(), "volume pointer matrix");
    putVec(S.data, m.data(), "volume blocks");
  } else {
    putVec(S.ptr, vol.brickPointers(), "volume brick pointers");
    if (S.storage == VoxelStorage::UInt8)
      putVec(S.data, vol.bricks8(), "volume 8-bit bricks");
    else
      putVec(S.data, vol.bricks16(), "volume 16-bit bricks");
    putVec(S.masks, vol.cellMasks(), "volume cell masks");
    putVec(S.dist, vol.brickDistances(), "volume empty cubes");
  }
  put(S.occ, occ.data(), occ.size(), "volume occupancy levels");
  run.finish();
  S.uploaded = true;
}

VolumeImage VolumeRenderer::render(const VolumeGeometry& geo, const TransferTable& tf, const VolumeCamera& cam,
                                   const VolumeRenderOptions& opt, std::vector<KernelTiming>* kernels) {
  const auto start = std::chrono::steady_clock::now();
  State& S = *st_;
  if (!S.uploaded) throw Error("OpenCL VolumeRenderer: no volume uploaded; call upload(volume) first");
  checkVolumeRenderArguments(geo, tf, cam, opt, "renderVolume (OpenCL)");
  const std::vector<float> table = stepCorrectedTable(tf, opt.sampleDistance);

  const int w = std::max(1, static_cast<int>(std::lround(cam.width / opt.imageSampleDistance)));
  const int h = std::max(1, static_cast<int>(std::lround(cam.height / opt.imageSampleDistance)));
  const double aspect = double(cam.width) / cam.height;
  const Vec3 fwd = normalized(cam.focalPoint - cam.position);
  const Vec3 right = normalized(cross(fwd, cam.viewUp));
  const Vec3 up = cross(right, fwd);
  const double th = std::tan(cam.viewAngle * 0.5 * 3.14159265358979323846 / 180.0);

  MtVolumeParams P = S.shape;
  for (int a = 0; a < 3; ++a) {
    P.eye[a] = cam.position[a];
    P.forward[a] = fwd[a];
    P.right[a] = right[a];
    P.up[a] = up[a];
    P.origin[a] = geo.origin[a];
    P.spacing[a] = geo.spacing[a];
  }
  P.tanHalfAngle = th;
  P.aspect = aspect;
  P.parallelScale = cam.parallelScale;
  P.dt = opt.sampleDistance;
  P.threshold = double(earlyTerminationThreshold(opt));  // the float the CPU compares against
  P.ambient = opt.ambient;
  P.diffuse = opt.diffuse;
  P.specular = opt.specular;
  P.specularPower = opt.specularPower;
  // The table's index map in sample units, as sampleUnits() (the CPU marchers' numbers).
  P.tableLo = tf.indexLo() / S.scale;
  P.tableScale = tf.indexScale() * S.scale;
  P.lastEntry = tf.lastIndex();
  P.skip = opt.emptySpaceSkipping ? 1 : 0;
  P.shade = opt.shade ? 1 : 0;
  P.parallel = cam.parallel ? 1 : 0;

  Context::Impl& impl = ctx_->impl();
  std::lock_guard<std::recursive_mutex> lock(impl.mutex);
  const size_t rays = size_t(w) * h;
  std::vector<float> small(rays * 4);
  std::vector<uint32_t> counts(rays * 2);
  {
    Launcher run(impl, kernels);
    auto put = [&](Buffer& b, const void* src, size_t bytes, const char* what) {
      b.ensure(impl, bytes, what);
      run.write(b, src, bytes, what);
    };
    put(S.params, &P, sizeof P, "volume parameters");
    put(S.table, table.data(), table.size() * sizeof(float), "transfer table");
    S.out.ensure(impl, small.size() * sizeof(float), "volume image");
    S.counts.ensure(impl, counts.size() * sizeof(uint32_t), "volume ray counters");
    const cl_int cw = w, ch = h;
    if (S.storage == VoxelStorage::Float32) {
      run.run(opt.doublePrecision ? "mt_volume_march_d" : "mt_volume_march_f", rays, 0, S.ptr, S.data, S.occ,
              S.params, S.table, S.out, S.counts, cw, ch);
    } else {
      // The apron marchers: the CPU's marchApron (float) or march() over apron bricks (double).
      const bool u8 = S.storage == VoxelStorage::UInt8;
      const char* name = opt.doublePrecision ? (u8 ? "mt_volume_apron_u8_d" : "mt_volume_apron_u16_d")
                                             : (u8 ? "mt_volume_apron_u8_f" : "mt_volume_apron_u16_f");
      run.run(name, rays, 0, S.ptr, S.data, S.masks, opt.doublePrecision ? S.occ : S.dist, S.params, S.table,
              S.out, S.counts, cw, ch);
    }
    run.read(S.out, small.data(), small.size() * sizeof(float), "volume image");
    run.read(S.counts, counts.data(), counts.size() * sizeof(uint32_t), "volume ray counters");
    run.finish();
  }

  VolumeImage img;
  img.width = cam.width;
  img.height = cam.height;
  img.rays = rays;
  for (size_t i = 0; i < rays; ++i) {
    img.samples += counts[2 * i];
    img.skips += counts[2 * i + 1];
  }
  if (w == cam.width && h == cam.height) {
    img.rgba = std::move(small);
  } else {
    // renderVolume's bilinear reconstruction from the coarse image, on the host.
    img.rgba = upsampleRGBA(small, w, h, cam.width, cam.height, resolveThreads(opt.threads));
  }
  img.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return img;
}

}  // namespace ocl
}  // namespace mtree

#endif  // MATRIXTREE_HAVE_OPENCL
