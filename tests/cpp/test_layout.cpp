// The structs of layout.h are shared with the OpenCL kernels: their sizes and field offsets are a
// contract, written beside every field in the header. These tests hold the header to it.
#include <gtest/gtest.h>

#include <cstddef>
#include <type_traits>

#include "mtree/core/block_sparse.h"
#include "mtree/core/layout.h"

namespace {

TEST(Layout, FieldTypesAre32Bit) {
  EXPECT_EQ(sizeof(mt_u32), 4u);
  EXPECT_EQ(sizeof(mt_i32), 4u);
  EXPECT_EQ(sizeof(mt_u8), 1u);
  EXPECT_TRUE(std::is_unsigned<mt_u32>::value);
  EXPECT_TRUE(std::is_signed<mt_i32>::value);
  EXPECT_EQ(MT_NULL, 0xFFFFFFFFu);
  EXPECT_EQ(MT_MAX_LOG_BLOCK, 5);
  EXPECT_EQ(MT_MAX_LEVELS, 64);
}

/// Uploaded to a device byte for byte: no vtable, no padding games, trivially copyable, aligned
/// to `align` bytes.
template <class T>
void expectPlainOldData(size_t align, const char* name) {
  EXPECT_TRUE(std::is_standard_layout<T>::value) << name;
  EXPECT_TRUE(std::is_trivially_copyable<T>::value) << name;
  EXPECT_EQ(alignof(T), align) << name;
}

TEST(Layout, StructsArePlainOldData) {
  expectPlainOldData<MtSparseDesc>(4, "MtSparseDesc");
  expectPlainOldData<MtLeafRange>(4, "MtLeafRange");
  expectPlainOldData<MtLevelDesc>(4, "MtLevelDesc");
}

TEST(Layout, LeafRangeIs8Bytes) {
  EXPECT_EQ(sizeof(MtLeafRange), 8u);
  EXPECT_EQ(offsetof(MtLeafRange, begin), 0u);
  EXPECT_EQ(offsetof(MtLeafRange, end), 4u);
}

// layout.h documents MtSparseDesc as 64 bytes ("pad: keeps the struct 64 bytes") and
// MtLevelDesc as 80 bytes (64 + 12 + 4).
TEST(Layout, SparseDescIs64Bytes) {
  EXPECT_EQ(sizeof(MtSparseDesc), 64u)
      << "layout.h: 9 x i32 + 5 x u32 = 56 bytes; the single `pad` field does not make 64";
}

TEST(Layout, SparseDescFieldOffsets) {
  EXPECT_EQ(offsetof(MtSparseDesc, dims), 0u);
  EXPECT_EQ(offsetof(MtSparseDesc, logBlock), 12u);
  EXPECT_EQ(offsetof(MtSparseDesc, ptrDims), 24u);
  EXPECT_EQ(offsetof(MtSparseDesc, blockVolume), 36u);
  EXPECT_EQ(offsetof(MtSparseDesc, numBlocks), 40u);
  EXPECT_EQ(offsetof(MtSparseDesc, ptrOffset), 44u);
  EXPECT_EQ(offsetof(MtSparseDesc, dataOffset), 48u);
  EXPECT_EQ(offsetof(MtSparseDesc, pad), 52u);
}

TEST(Layout, LevelDescIs80Bytes) {
  EXPECT_EQ(sizeof(MtLevelDesc), 80u) << "layout.h documents 64 + 12 + 4 = 80 bytes";
  // The level fields follow the matrix, whatever its size.
  EXPECT_EQ(offsetof(MtLevelDesc, matrix), 0u);
  EXPECT_EQ(offsetof(MtLevelDesc, logDims), sizeof(MtSparseDesc));
  EXPECT_EQ(offsetof(MtLevelDesc, pad), sizeof(MtSparseDesc) + 12u);
  EXPECT_EQ(offsetof(MtLevelDesc, logDims), 64u);
  EXPECT_EQ(offsetof(MtLevelDesc, pad), 76u);
}

TEST(Layout, ArraysOfDescriptorsHaveNoGaps) {
  // Kernels index level descriptors as a flat array: element i starts at i * sizeof.
  MtLevelDesc levels[3];
  EXPECT_EQ(reinterpret_cast<const char*>(&levels[2]) - reinterpret_cast<const char*>(&levels[0]),
            static_cast<std::ptrdiff_t>(2 * sizeof(MtLevelDesc)));
  MtLeafRange ranges[4];
  EXPECT_EQ(reinterpret_cast<const char*>(&ranges[3]) - reinterpret_cast<const char*>(&ranges[0]), 24);
}

// The kernels' parameter structs: doubles first, then 4-byte fields, each a multiple of 8 bytes,
// so the device's OpenCL C layout (natural alignment) is the host's.
TEST(Layout, ParameterStructsArePlainOldData) {
  expectPlainOldData<MtBuildParams>(8, "MtBuildParams");
  expectPlainOldData<MtTreeGeom>(8, "MtTreeGeom");
  expectPlainOldData<MtVolumeLevel>(4, "MtVolumeLevel");
  expectPlainOldData<MtVolumeParams>(8, "MtVolumeParams");
}

TEST(Layout, BuildParamsAre96Bytes) {
  EXPECT_EQ(sizeof(MtBuildParams), 96u);
  EXPECT_EQ(offsetof(MtBuildParams, origin), 0u);
  EXPECT_EQ(offsetof(MtBuildParams, invLeaf), 24u);
  EXPECT_EQ(offsetof(MtBuildParams, leafSize), 48u);
  EXPECT_EQ(offsetof(MtBuildParams, halfSize), 72u);
}

TEST(Layout, TreeGeomIs1608Bytes) {
  EXPECT_EQ(sizeof(MtTreeGeom), 1608u);
  EXPECT_EQ(offsetof(MtTreeGeom, lo), 0u);
  EXPECT_EQ(offsetof(MtTreeGeom, hi), 24u);
  EXPECT_EQ(offsetof(MtTreeGeom, invLeaf), 48u);
  EXPECT_EQ(offsetof(MtTreeGeom, cellSize), 72u);
  EXPECT_EQ(sizeof(MtTreeGeom::cellSize), size_t(MT_MAX_LEVELS) * 24u) << "a node size for every level";
}

TEST(Layout, VolumeLevelIs16Bytes) {
  EXPECT_EQ(sizeof(MtVolumeLevel), 16u);
  EXPECT_EQ(offsetof(MtVolumeLevel, dims), 0u);
  EXPECT_EQ(offsetof(MtVolumeLevel, occOffset), 12u);
}

TEST(Layout, VolumeParamsAre800Bytes) {
  EXPECT_EQ(MT_VOLUME_MAX_LEVELS, 32);
  EXPECT_EQ(sizeof(MtVolumeParams), 800u);
  EXPECT_EQ(offsetof(MtVolumeParams, eye), 0u);
  EXPECT_EQ(offsetof(MtVolumeParams, forward), 24u);
  EXPECT_EQ(offsetof(MtVolumeParams, right), 48u);
  EXPECT_EQ(offsetof(MtVolumeParams, up), 72u);
  EXPECT_EQ(offsetof(MtVolumeParams, tanHalfAngle), 96u);
  EXPECT_EQ(offsetof(MtVolumeParams, aspect), 104u);
  EXPECT_EQ(offsetof(MtVolumeParams, parallelScale), 112u);
  EXPECT_EQ(offsetof(MtVolumeParams, origin), 120u);
  EXPECT_EQ(offsetof(MtVolumeParams, spacing), 144u);
  EXPECT_EQ(offsetof(MtVolumeParams, dt), 168u);
  EXPECT_EQ(offsetof(MtVolumeParams, threshold), 176u);
  EXPECT_EQ(offsetof(MtVolumeParams, ambient), 184u);
  EXPECT_EQ(offsetof(MtVolumeParams, diffuse), 192u);
  EXPECT_EQ(offsetof(MtVolumeParams, specular), 200u);
  EXPECT_EQ(offsetof(MtVolumeParams, specularPower), 208u);
  EXPECT_EQ(offsetof(MtVolumeParams, tableLo), 216u);
  EXPECT_EQ(offsetof(MtVolumeParams, tableScale), 220u);
  EXPECT_EQ(offsetof(MtVolumeParams, offset), 224u);
  EXPECT_EQ(offsetof(MtVolumeParams, dims), 228u);
  EXPECT_EQ(offsetof(MtVolumeParams, logBlock), 240u);
  EXPECT_EQ(offsetof(MtVolumeParams, ptrDims), 252u);
  EXPECT_EQ(offsetof(MtVolumeParams, blockVolume), 260u);
  EXPECT_EQ(offsetof(MtVolumeParams, levels), 264u);
  EXPECT_EQ(offsetof(MtVolumeParams, lastEntry), 268u);
  EXPECT_EQ(offsetof(MtVolumeParams, skip), 272u);
  EXPECT_EQ(offsetof(MtVolumeParams, shade), 276u);
  EXPECT_EQ(offsetof(MtVolumeParams, parallel), 280u);
  EXPECT_EQ(offsetof(MtVolumeParams, pad), 284u);
  EXPECT_EQ(offsetof(MtVolumeParams, level), 288u);
}

TEST(Layout, BlockSparseDescriptorFillsTheSharedStruct) {
  // The host matrix hands the kernels exactly this struct: its fields must describe the matrix.
  mtree::BlockSparseMatrix<uint8_t> m(37, 5, 64, 8, 0);
  const MtSparseDesc& d = m.desc();
  EXPECT_EQ(d.dims[0], 37);
  EXPECT_EQ(d.dims[1], 5);
  EXPECT_EQ(d.dims[2], 64);
  EXPECT_EQ(d.logBlock[0], 3);
  EXPECT_EQ(d.logBlock[1], 3);  // 5 entries: the block is shrunk to the next power of two, 8
  EXPECT_EQ(d.logBlock[2], 3);
  EXPECT_EQ(d.ptrDims[0], 5);
  EXPECT_EQ(d.ptrDims[1], 1);
  EXPECT_EQ(d.ptrDims[2], 8);
  EXPECT_EQ(d.blockVolume, 512u);
  EXPECT_EQ(d.numBlocks, 0u);
}

}  // namespace
