"""pyproject.toml lists every package of the driver: a built wheel (not only the editable install
the tests run from) carries them all."""
import pytest

from tests.conftest import REPO


def test_every_driver_package_is_listed():
    tomllib = pytest.importorskip("tomllib", reason="tomllib is Python 3.11+")
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(REPO).parts) for p in (REPO / "roadx_ti").rglob("__init__.py")}
    assert found <= listed, f"not in pyproject.toml's packages: {sorted(found - listed)}"
    assert "roadx_ti.kernels" in listed
