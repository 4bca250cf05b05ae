/* Data layout shared by the C++ engine and the OpenCL kernels.
 *
 * Everything a kernel reads is a plain struct of 32-bit fields plus flat arrays addressed by
 * 32-bit offsets, so the host arrays can be uploaded unchanged (the NanoVDB/CNanoVDB habit).
 * Byte counts are written beside every field; tests/cpp/test_layout.cpp asserts the sizes.
 */
#ifndef MTREE_LAYOUT_H
#define MTREE_LAYOUT_H

#ifdef __OPENCL_VERSION__
typedef uint mt_u32;
typedef int mt_i32;
typedef uchar mt_u8;
#else
#include <cstdint>
typedef uint32_t mt_u32;
typedef int32_t mt_i32;
typedef uint8_t mt_u8;
#endif

/* Marks an unallocated block in a pointer matrix and an absent node in a leaf range. */
#define MT_NULL 0xFFFFFFFFu

/* Largest tree height (levels below the root) and largest block edge we accept. */
#define MT_MAX_LEVELS 64
#define MT_MAX_LOG_BLOCK 5

/* One block-sparse matrix (paper §3): a dense pointer matrix over blocks of
 * 2^logBlock[0] x 2^logBlock[1] x 2^logBlock[2] entries; only blocks that hold data exist.
 * Access is two reads: pointer matrix, then the block. 64 bytes. */
typedef struct MtSparseDesc {
  mt_i32 dims[3];     /* 12: entries per axis */
  mt_i32 logBlock[3]; /* 12: log2 of the block edge per axis */
  mt_i32 ptrDims[3];  /* 12: pointer-matrix size per axis, ceil(dims / blockEdge) */
  mt_u32 blockVolume; /*  4: entries per block */
  mt_u32 numBlocks;   /*  4: allocated blocks */
  mt_u32 ptrOffset;   /*  4: first pointer of this matrix in a concatenated pointer array */
  mt_u32 dataOffset;  /*  4: first entry of this matrix in a concatenated data array */
  mt_u32 pad[3];      /* 12: keeps the struct 64 bytes */
} MtSparseDesc;

/* A leaf's primitive range [begin, end) in the tree's primitive index array.
 * begin == MT_NULL means the leaf does not exist. 8 bytes. */
typedef struct MtLeafRange {
  mt_u32 begin; /* 4 */
  mt_u32 end;   /* 4 */
} MtLeafRange;

/* One level of a matrix tree: its node grid and block-sparse storage. 80 bytes.
 * logDims[a] = log2(nodes along axis a); node extent along a = rootExtent[a] / 2^logDims[a]. */
typedef struct MtLevelDesc {
  MtSparseDesc matrix; /* 64 */
  mt_i32 logDims[3];   /* 12 */
  mt_i32 pad;          /*  4 */
} MtLevelDesc;

#endif
