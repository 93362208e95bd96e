"""roadx_ti: road surface and building roof extraction from point clouds on Taichi kernels."""
import os as _os

# Taichi prints a banner on import; keep stdout clean for `roadx_ti eval` JSON (a host program
# that wants it can set the variable itself before importing us).
_os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "0")

__version__ = "0.1.0"
