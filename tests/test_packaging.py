"""An installed wheel (not only an editable checkout) holds every module, finds its shaders and scenes,
and simulates and renders from outside the source tree."""
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
    # every module of the source tree, and nothing else (a stale build/ folder would add deleted ones)
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / "fraytool").rglob("*.py")}
    assert {n for n in names if n.endswith(".py")} == modules
    for scene in (ROOT / "scenes").glob("*.toml"):
        assert f"fraytool/scenes/{scene.name}" in names
    for asset in (ROOT / "scenes" / "assets").rglob("*"):  # the mesh files shipped scenes name
        if asset.is_file():
            assert f"fraytool/scenes/{asset.relative_to(ROOT / 'scenes').as_posix()}" in names
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
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "fraytool", "simulate", "drape", "--frames", "2", "-o", str(out)],
                       cwd=elsewhere, capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert (out / "frames" / "manifest.json").is_file()
    r = subprocess.run([sys.executable, "-m", "fraytool", "render", "drape", "--frames", "0:1", "--png", "--no-mp4",
                        "--resolution", "64x48", "-o", str(out)], cwd=elsewhere, capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert len(list((out / "png").glob("*.png"))) == 1
