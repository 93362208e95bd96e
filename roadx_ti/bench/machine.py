"""Facts about the machine a run measured on (CPU, memory, versions, Vulkan and CUDA devices)."""
from __future__ import annotations

import importlib.util
import os
import platform
import shutil
import subprocess
from pathlib import Path


def machine_facts(backends) -> dict:
    facts = {"cpu_model": _cpu_model(), "logical_cores": os.cpu_count(),
             "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
             "memory_gb": _mem_total_gb(), "os": platform.platform(), "python": platform.python_version(),
             "versions": _versions(), "synthetic": _synthetic_source()}
    if "vulkan" in backends:
        facts["vulkan"] = _vulkan_device()
    if "cuda" in backends:
        facts["cuda"] = _cuda_device()
    return facts


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _mem_total_gb():
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        return None


def _versions() -> dict:
    from importlib import metadata

    out = {}
    for dist in ("roadx_ti", "taichi", "numpy", "scipy", "open3d-cpu", "open3d", "cloth-simulation-filter", "pykdtree"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


def _synthetic_source() -> str:
    return "roadx_ti.synthetic" if importlib.util.find_spec("roadx_ti.synthetic") else \
        "stand-in generator of roadx_ti.bench (roadx_ti.synthetic absent)"


def _vulkan_device():
    exe = shutil.which("vulkaninfo")
    if not exe:
        return {"note": "vulkaninfo not installed"}
    try:
        text = subprocess.run([exe, "--summary"], capture_output=True, text=True, timeout=20).stdout
    except (subprocess.SubprocessError, OSError) as exc:
        return {"note": f"vulkaninfo failed: {exc}"}
    devices, current = [], None
    for line in text.splitlines():
        key, _, value = (s.strip() for s in line.partition("="))
        if key == "apiVersion":
            current = {"api": value}
            devices.append(current)
        elif current is not None and key in ("deviceName", "driverName", "driverInfo", "deviceType"):
            current[key] = value
    return devices


def _cuda_device():
    exe = shutil.which("nvidia-smi")
    if not exe:
        return {"note": "no nvidia-smi: no CUDA device"}
    try:
        text = subprocess.run([exe, "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                              capture_output=True, text=True, timeout=20).stdout.strip()
    except (subprocess.SubprocessError, OSError) as exc:
        return {"note": f"nvidia-smi failed: {exc}"}
    return [dict(zip(("name", "driver", "memory"), (s.strip() for s in line.split(","))))
            for line in text.splitlines() if line.strip()]

