// Private to engine/src/volume: what the files of the volume renderer hand each other. Plain data
// only (no inline code), so that the AVX2 file (march_avx2.cpp, compiled with -mavx2) and the
// others share types, never compiled code: the code they share is in march.h's unnamed namespace,
// a copy per file.
//
//   transfer_table.cpp  TransferTable, stepCorrectedTable
//   classify.cpp        BlockSparseVolume::classify and sample: the storage and the levels
//   march.h             the general marcher march() and the SSE2 marcher marchApron()
//   march_avx2.cpp      the AVX2 marcher and 4-ray set-up, chosen at run time (cpuHasAvx2)
//   render.cpp          renderVolume: the frame, the image in tiles, the marcher per ray
//   upsample.cpp        upsampleRGBA
#pragma once

#include <cstdint>

#include "mtree/volume/volume.h"

namespace mtree {
namespace volume_detail {

constexpr int LOG2DIM = BlockSparseVolume::LOG2DIM;
constexpr int DIM = BlockSparseVolume::DIM;

/// Per-frame constants of the marchers (copied by value into each ray's loop).
struct Frame {
  const BlockSparseVolume* vol;
  int n[3];             // points per axis
  int nb[3];            // level-0 bricks per axis
  const float* table;   // premultiplied, opacity corrected for the step: 4 per entry, 16-byte aligned
  const float* table8;  // AVX2 marcher: 8 per entry, the 4 above and 1 - opacity 4 times (the factor
                        // of the transmittance, computed once per frame instead of per sample), 32-byte aligned
  float tlo, tscale;
  int tlast;
  float offset;  // added to an interpolated stored value
  double dt;     // world units per step
  float threshold;
  int lanes;    // 8: the unshaded UInt8/UInt16 float rays take the AVX2 marcher; 1: the SSE2 one
  bool setup4;  // perspective rays are set up 4 at a time with AVX2 (setupRays4: the same rays)
  const uint8_t* dist;        // BlockSparseVolume::brickDistances
  const uint32_t* runBricks;  // AVX2 marcher: per level-0 brick its stored brick's first entry where the walk may
                              // march through it, MT_NULL where it stops (absent; skipping: invisible)
  double spacing[3];
  double ambient, diffuse, specular, specularPower;
};

/// A ray of a tile queued for the AVX2 marcher (index-space origin and direction, entry, last
/// sample, its pixel), and a tile's queue.
struct PendingRay {
  double ro[3], rd[3], t0;
  int64_t kEnd;
  float* out;
};
struct PendingRayList {
  static constexpr int CAPACITY = 64;
  PendingRay rays[CAPACITY];
  int count = 0;
};

/// The UInt8/UInt16 apron bricks as the marchers read them (BlockSparseVolume's arrays): brick
/// pointers in level-0 order (MT_NULL: absent), the bricks, DIM visible-cell words per level-0
/// brick, and the level-0 bricks along x and y. Voxel: how the bricks hold their voxels.
enum class ApronVoxel { UInt8, Paired8, UInt16 };
struct ApronBricks {
  const uint32_t* ptr;
  const void* data;
  const uint64_t* masks;
  int nb0, nb1;
};

/// A perspective ray in index space as the image loop sets it up: origin (the eye, the same for
/// all), direction rd, entry t0 and last sample kEnd; d the unit world direction (the headlight).
struct PixelRay {
  double rd[3], t0, d[3];
  int64_t kEnd;
  bool hit;  // false: the ray misses the box (its pixel stays 0)
};

/// The per-frame numbers of a perspective ray's set-up (the image loop's expressions).
struct RaySetupFrame {
  double fwd[3], spacing[3], roEye[3], hiIdx[3], dt;
  const double* rightX[3];  // per column: right * (nx th aspect), one array per axis (padded by 3)
  double upY[3];            // the row's up * (ny th)
};

// ---- march_avx2.cpp: call only where cpuHasAvx2() (render.cpp) is true ------------------------

/// The AVX2 marcher for `count` queued rays of a tile: each ray's image, samples and skips are
/// marchApron<T, Skip, false>'s exactly (march.h), for rays of at most 2^24 - 8 samples.
void marchApronAvx2(const Frame& F, const ApronBricks& bricks, ApronVoxel voxel, bool skip, const PendingRay* rays,
                    int count, uint64_t& samples, uint64_t& skips);

/// setupRay (render.cpp) for pixel columns x..x+3 of the row in S at once: the same rays bit for bit.
void setupRays4(const RaySetupFrame& S, int x, PixelRay r[4]);

// ---- render.cpp, for march_avx2.cpp ----------------------------------------------------------

/// march.h's apronClampedSample<false> at the position p (x, y, z, then any): the sample where
/// it needs clamping, composited into (C, T) (AccT's sums). True when the ray is opaque. Compiled
/// in render.cpp for the baseline instruction set, as the BlockSparseVolume::cellCornersInSampleUnits it reads.
bool clampedSampleUnshaded(const Frame& F, const float p[4], float C[4], float& T, uint64_t& samples);

}  // namespace volume_detail
}  // namespace mtree
