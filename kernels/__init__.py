"""Taichi kernels of roadx_ti, installed as ``roadx_ti.kernels``.

Each module holds ``@ti.kernel``/``@ti.func`` code plus thin public wrappers that take numpy
arrays or Taichi ndarrays owned by the caller. Nothing here calls ``ti.init``, reads files,
parses configuration or prints: the host program (or ``roadx_ti.backend``) initialises Taichi.
"""
