/* Data layout shared by the C++ engine and the OpenCL kernels.
 *
 * Everything a kernel reads is a plain struct of 32-bit fields (its parameters: doubles, then
 * 32-bit fields) plus flat arrays addressed by 32-bit offsets, so the host arrays can be uploaded
 * unchanged (the NanoVDB/CNanoVDB habit). Byte counts are written beside every field;
 * tests/cpp/test_layout.cpp asserts the sizes and offsets.
 */
#ifndef MTREE_LAYOUT_H
#define MTREE_LAYOUT_H

#ifdef __OPENCL_VERSION__
#pragma OPENCL EXTENSION cl_khr_fp64 : enable /* the parameter structs hold doubles */
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

/* The parameters of the kernels, one struct per kernel family, uploaded as one buffer each and
 * read through a __global pointer. Doubles first, then 4-byte fields, each struct a multiple of
 * 8 bytes: the same offsets under the host's C++ and the device's OpenCL C rules (natural
 * alignment, no packing). */

/* The §5.1 build kernels (opencl/build.cl): the leaf grid as MatrixTreeBuilder computes with it.
 * 96 bytes. */
typedef struct MtBuildParams {
  double origin[3];   /* 24: the root box's lo corner */
  double invLeaf[3];  /* 24: 1 / leaf size per axis (MatrixTree::invLeaf_) */
  double leafSize[3]; /* 24: leaf size per axis */
  double halfSize[3]; /* 24: half a leaf's size, padded for round-off (the candidate test's box) */
} MtBuildParams;

/* The query kernels (opencl/query.cl, query_cells.cl): a matrix tree's geometry. 1608 bytes. */
typedef struct MtTreeGeom {
  double lo[3];                      /*   24: the root box */
  double hi[3];                      /*   24 */
  double invLeaf[3];                 /*   24: 1 / leaf size, as the builder computes it */
  double cellSize[MT_MAX_LEVELS][3]; /* 1536: node size per axis of levels 0..height */
} MtTreeGeom;

/* One level of a volume's empty-space hierarchy (BlockSparseVolume::nodeVisible): nodes per
 * axis and where its occupancy bytes start in the concatenated array. 16 bytes. */
typedef struct MtVolumeLevel {
  mt_i32 dims[3];   /* 12 */
  mt_u32 occOffset; /*  4 */
} MtVolumeLevel;

/* Levels a volume can have: level 0 has ceil((n - 1) / 8) < 2^28 bricks per axis. */
#define MT_VOLUME_MAX_LEVELS 32

/* The volume kernels (opencl/volume.cl): the camera, the volume's shape and storage, the table
 * and the options, as renderVolume computes them. 800 bytes. */
typedef struct MtVolumeParams {
  double eye[3];        /* 24: camera position (world) */
  double forward[3];    /* 24: unit view direction */
  double right[3];      /* 24: unit right vector */
  double up[3];         /* 24: unit up vector */
  double tanHalfAngle;  /*  8: tan of half the vertical view angle */
  double aspect;        /*  8: image width / height */
  double parallelScale; /*  8: half the view height (parallel projection) */
  double origin[3];     /* 24: world position of grid point (0, 0, 0) */
  double spacing[3];    /* 24: world units between grid points */
  double dt;            /*  8: world units between samples */
  double threshold;     /*  8: early termination: the float the CPU compares against */
  double ambient;       /*  8: shading */
  double diffuse;       /*  8 */
  double specular;      /*  8 */
  double specularPower; /*  8 */
  float tableLo;        /*  4: TransferTable::indexLo */
  float tableScale;     /*  4: TransferTable::indexScale */
  float offset;         /*  4: added to a stored 8/16-bit value (BlockSparseVolume::storageOffset) */
  mt_i32 dims[3];       /* 12: grid points per axis */
  mt_i32 logBlock[3];   /* 12: float blocks: log2 of the block edge per axis */
  mt_i32 ptrDims[2];    /*  8: float blocks: pointer matrix size along x and y */
  mt_u32 blockVolume;   /*  4: float blocks: entries per block */
  mt_i32 levels;        /*  4: levels of the empty-space hierarchy */
  mt_i32 lastEntry;     /*  4: TransferTable::lastIndex */
  mt_i32 skip;          /*  4: empty-space skipping on */
  mt_i32 shade;         /*  4: gradient shading on */
  mt_i32 parallel;      /*  4: parallel projection */
  mt_i32 pad;           /*  4: keeps the levels at a multiple of 8 bytes */
  MtVolumeLevel level[MT_VOLUME_MAX_LEVELS]; /* 512 */
} MtVolumeParams;

#endif
