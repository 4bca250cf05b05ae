// Private to the MatrixTree::Filters module and its tests and benchmarks (C++ only: not wrapped,
// not installed): the developer settings of vtkMatrixTreeVolumeRayCaster, set through its
// SetTuning. Each is an alternative that the production path is checked or timed against, and
// each gives the same image as the defaults but ExactFloat, which bounds the error of the default
// (tests/cpp/test_volume_filter.cpp holds them to it;
// bench/cpp/volume_ab.cxx times them against each other).
#ifndef vtkMatrixTreeVolumeTuning_h
#define vtkMatrixTreeVolumeTuning_h

struct vtkMatrixTreeVolumeTuning
{
  /// Skip invisible nodes of the matrix-tree levels (mtree::VolumeRenderOptions::emptySpaceSkipping).
  /// false: march through every node; the same image bit for bit, slower.
  bool EmptySpaceSkipping = true;
  /// Allocate every block or brick (mtree::VolumeBuildOptions::sparse off): the dense reference,
  /// same code path, the same image. Changing it reclassifies the volume.
  bool DenseStorage = false;
  /// Keep floating-point scalars exact (mtree::VolumeBuildOptions::quantizeFloat off): Float32
  /// blocks instead of the 16-bit bricks they are quantised into when the transfer table cannot
  /// resolve the quantisation step. The reference the quantised path's error bound is checked
  /// against; not the same image (within that bound). Changing it reclassifies the volume.
  bool ExactFloat = false;
  /// The AVX2 marcher and ray set-up where the CPU has them (mtree::VolumeRenderOptions::vectorized).
  /// false: the SSE2 marcher and the scalar set-up, the same image bit for bit.
  bool Vectorized = true;

  bool operator==(const vtkMatrixTreeVolumeTuning& o) const
  {
    return this->EmptySpaceSkipping == o.EmptySpaceSkipping && this->DenseStorage == o.DenseStorage &&
      this->Vectorized == o.Vectorized && this->ExactFloat == o.ExactFloat;
  }
  bool operator!=(const vtkMatrixTreeVolumeTuning& o) const { return !(*this == o); }
};

#endif
