"""Rules every kernel file keeps, read from the sources (they fail on a backend CI has no device for)."""
import ast
from pathlib import Path

import pytest

KERNEL_DIR = Path(__file__).resolve().parents[1] / "kernels"
CUDA_MAX_BLOCK_DIM = 1024      # Taichi's taichi_max_gpu_block_dim: larger asserts when a CUDA kernel compiles


def _loop_configs(path):
    tree = ast.parse(path.read_text())
    constants = {t.id: node.value.value for node in tree.body if isinstance(node, ast.Assign)
                 for t in node.targets if isinstance(t, ast.Name) and isinstance(node.value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and ast.unparse(node.func) == "ti.loop_config":
            for kw in node.keywords:
                if kw.arg == "block_dim":
                    yield node.lineno, kw.value, constants


@pytest.mark.parametrize("path", sorted(KERNEL_DIR.glob("*.py")), ids=lambda p: p.name)
def test_block_dims_compile_on_cuda(path):
    # block_dim is a CPU thread's share of iterations on the CPU but threads per block on GPUs:
    # a CPU-sized value goes through common.cpu_block_dim (the GPU default elsewhere), and a plain
    # value must be a valid GPU block (kernels/grid.py's 4096 failed every CUDA run until 2026-12-04).
    for line, value, constants in _loop_configs(path):
        text = ast.unparse(value)
        if text.startswith("ti.static(cpu_block_dim(") and text.count("(") == 2:
            continue
        number = value.value if isinstance(value, ast.Constant) else constants.get(text)
        assert isinstance(number, int) and 1 <= number <= CUDA_MAX_BLOCK_DIM, \
            f"{path.name}:{line}: block_dim={text} is not a valid CUDA block; use cpu_block_dim()"


def test_the_rule_sees_the_loop_configs():
    found = [text for p in KERNEL_DIR.glob("*.py") for _, v, _ in _loop_configs(p) for text in [ast.unparse(v)]]
    assert any(t.startswith("ti.static(cpu_block_dim(") for t in found) and len(found) >= 3
