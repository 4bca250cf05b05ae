"""The Python side of the build: the wrapped VTK module and the package."""

import vtkmodules.vtkCommonCore as vtk_core


def test_vtk_is_debian_9_1():
    # matrixtree_vtk is compiled against Debian's VTK 9.1; any other VTK in
    # the process (pip's wheel) would crash it.
    assert vtk_core.vtkVersion.GetVTKMajorVersion() == 9
    assert vtk_core.vtkVersion.GetVTKMinorVersion() == 1
    assert vtk_core.vtkVersion.GetVTKVersion().startswith("9.1.")


def test_wrapped_class_imports():
    from matrixtree_vtk import vtkMatrixTreeVersion

    obj = vtkMatrixTreeVersion()
    assert isinstance(obj, vtk_core.vtkObject)
    assert obj.GetClassName() == "vtkMatrixTreeVersion"
    assert "Version: " in str(obj)


def test_package_version_matches_wrapped_library():
    import matrixtree
    from matrixtree_vtk import vtkMatrixTreeVersion

    assert vtkMatrixTreeVersion.GetVersion() == matrixtree.__version__
    assert matrixtree.__version__ == "0.1.0"
