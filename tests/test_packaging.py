"""Shaders and scenes are found from an installed wheel, not only from an editable checkout."""
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

PROBE = """
import sys
from fraytool import resources
from fraytool.scene import load_scene
print(resources.shader_dir())
print(resources.scenes_dir())
print(load_scene("scenes/drape.toml").name)
"""


def test_wheel_ships_scenes_and_shaders_and_finds_them(tmp_path):
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                        "-w", str(tmp_path / "dist"), str(ROOT)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    wheel = next((tmp_path / "dist").glob("fraytool-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    for scene in (ROOT / "scenes").glob("*.toml"):
        assert f"fraytool/scenes/{scene.name}" in names
    shaders = [p.name for p in (ROOT / "shaders").iterdir() if p.suffix in (".vert", ".frag")]
    for shader in shaders:
        assert f"fraytool/shaders/{shader}" in names
    target = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target),
                        str(wheel)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    r = subprocess.run([sys.executable, "-c", PROBE], cwd=elsewhere, capture_output=True, text=True,
                       env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    shader_dir, scenes_dir, name = r.stdout.split()
    assert shader_dir.startswith(str(target)) and scenes_dir.startswith(str(target))
    assert name == "drape"
