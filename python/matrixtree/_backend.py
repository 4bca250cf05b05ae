"""Which compiled extension answers the package's calls, decided once per process.

Two extensions implement the same queries: the VTK module ``matrixtree_vtk`` (the VTK classes,
built by ``scripts/setup.sh`` against Debian's VTK 9.1 SDK) and the engine extension
``matrixtree_engine`` (the VTK-free engine, built by ``pip install .`` where pip's VTK wheels
ship no C++ SDK). Where the VTK module imports it answers every call; elsewhere the engine
extension does (``matrixtree._engine``). There is no per-call fallback: each public name is bound
to one of the two when the package is imported.

A VTK module that is present but fails to load (a build for another VTK) raises its own
ImportError instead of silently switching paths.

Not public API.
"""

from __future__ import annotations

try:
    import matrixtree_vtk  # noqa: F401
except ModuleNotFoundError as e:
    if e.name != "matrixtree_vtk":
        raise
    VTK_MODULE = False
else:
    VTK_MODULE = True


def engine():
    """The engine extension ``matrixtree_engine``; ImportError saying how to build it if absent."""
    try:
        import matrixtree_engine
    except ModuleNotFoundError as e:
        if e.name != "matrixtree_engine":
            raise
        raise ImportError("matrixtree needs one of its compiled extensions: neither matrixtree_vtk (the VTK "
                          "module: bash scripts/setup.sh) nor matrixtree_engine (pip install .) imports") from None
    return matrixtree_engine
