"""roadx_ti: road surface and building roof extraction from point clouds on Taichi kernels."""

__version__ = "0.1.0"
