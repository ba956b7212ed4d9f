"""`cmake --install` gives an importable package that finds the installed gmsh worker."""

import os
import subprocess
import sys

from conftest import BUILD, REPO


def test_installed_package_imports_and_meshes(tmp_path):
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(BUILD), "--prefix", str(prefix)], check=True,
                   capture_output=True)
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    site = prefix / "lib" / version / "dist-packages"
    assert (site / "bsms" / "__init__.py").exists()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "BSMS_GMSH_WORKER")}
    env["PYTHONPATH"] = str(site)
    script = (
        "import os, bsms\n"
        "assert bsms.__file__.startswith(%r), bsms.__file__\n"
        "assert os.environ['BSMS_GMSH_WORKER'] == %r\n"
        "mesh = bsms.read_mesh(%r)\n"
        "levels = bsms.multilevel(mesh['positions'], mesh['cells'])\n"
        "print(len(levels), levels[0]['num_nodes'])\n"
        % (str(site), str(prefix / "bin" / "bsms-gmsh-worker"),
           str(REPO / "configs/geometry/plate_hole.geo")))
    done = subprocess.run([sys.executable, "-c", script], cwd="/", env=env, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    levels, nodes = map(int, done.stdout.split())
    assert levels >= 2 and nodes > 100
