# SPDX-License-Identifier: Apache-2.0
"""`pip install --no-build-isolation` of this package works offline and installs an importable fovea.

The source is copied first so that the build's by-products (build/, *.egg-info) stay out of the tree.
"""

import os
import shutil
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

SOURCE = Path(os.environ.get("FOVEA_PYTHON_SOURCE", Path(__file__).resolve().parents[1]))


def pip_available():
    return subprocess.run([sys.executable, "-m", "pip", "--version"], capture_output=True).returncode == 0


class Install(unittest.TestCase):
    @unittest.skipUnless(pip_available(), f"pip is not installed for {sys.executable} (Debian: python3-pip)")
    def test_offline_install_into_a_target_directory(self):
        with tempfile.TemporaryDirectory() as d:
            src = Path(d) / "src"
            shutil.copytree(SOURCE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
            target = Path(d) / "site"
            env = dict(os.environ, PIP_NO_INDEX="1", PIP_DISABLE_PIP_VERSION_CHECK="1")
            env.pop("PYTHONPATH", None)
            done = subprocess.run([sys.executable, "-m", "pip", "install", "--no-build-isolation", "--no-deps",
                                   "--no-index", "--target", str(target), str(src)],
                                  capture_output=True, text=True, env=env, timeout=120)
            self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
            env["PYTHONPATH"] = str(target)
            check = subprocess.run([sys.executable, "-c", "import fovea, fovea.client, fovea.recording; "
                                    "print(fovea.__version__, fovea.__file__)"],
                                   capture_output=True, text=True, env=env, cwd=d, timeout=30)
            self.assertEqual(check.returncode, 0, check.stderr)
            version, path = check.stdout.split()
            self.assertEqual(version, "0.1.0")
            self.assertTrue(path.startswith(str(target)), path)
            self.assertTrue(list(target.glob("fovea-0.1.0.dist-info")), sorted(os.listdir(target)))


if __name__ == "__main__":
    unittest.main()
