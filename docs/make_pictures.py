"""Regenerate the pictures of the README and docs/ from bundled samples (``make pictures``).

Each picture is the summary preview of one bundled config, run in a temporary folder, scaled to
at most :data:`MAX_WIDTH` pixels wide and written to ``docs/images/<name>.png`` under
:data:`MAX_BYTES` (scaled down further until it fits). With Debian's chromium installed, the review
page of those runs is rendered too (``docs/images/review.png``).

With the third-party models in ``../shared/data`` (see its SOURCES.md; never copied here), the
real-model pictures are rendered too: the input above the result, textured, from the front, iso
and top views, framed alike (:data:`REAL`). Without them those pictures are kept as they are.

Run: ``.venv/bin/python docs/make_pictures.py``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2

ROOT = Path(__file__).resolve().parent.parent
IMAGES = ROOT / "docs" / "images"
MAX_WIDTH = 960
MAX_BYTES = 200_000

PICTURES = {
    "retarget": ("configs/retarget/facade.yaml", "comparison.png"),
    "petri-synth": ("configs/petri-synth/building_ring.yaml", None),
    "symmetry-texture": ("configs/symmetry-texture/transfer.yaml", None),
    "surface-by-numbers": ("configs/surface-by-numbers/painted.yaml", None),
    "surface-by-numbers-transfer": ("configs/surface-by-numbers/transfer-stripes.yaml", None),
    "reshape": ("configs/reshape/facade-texture.yaml", None),
}
"""Picture name -> (the bundled config, the preview it shows; None: the run's summary preview)."""


SHARED = ROOT.parent / "shared" / "data"
REAL = {
    "petri-kenney-ring": (f"""method: petri-synth
example: {SHARED}/meshes/kenney-city/building-small-a.glb
lattice: {{unit: [0.5, 0.475, 0.5]}}
construction: {{plane: xz, points: [[0, 0], [0, 3], [4, 3], [4, 0]], closed: true}}
output: {{mesh_format: glb}}
""", "meshes/kenney-city/building-small-a.glb", "result.glb"),
    "reshape-house1-wider": (f"""method: reshape
input: {SHARED}/architecture/houses/house1_baked.obj
scale: {{x: 1.3}}
""", "architecture/houses/house1_baked.obj", "house1_baked.obj"),
}
"""Picture name -> (config text, input relative to ../shared/data, the result's file in the run folder)."""


def fitted_png(source: Path, target: Path) -> int:
    """Write ``source`` scaled to fit :data:`MAX_WIDTH` and :data:`MAX_BYTES` as ``target``; its size."""
    img = cv2.imread(str(source), cv2.IMREAD_COLOR)
    if img is None:
        raise SystemExit(f"{source}: cannot read the preview")
    width = min(MAX_WIDTH, img.shape[1])
    while True:
        height = max(1, round(img.shape[0] * width / img.shape[1]))
        scaled = cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA) if width < img.shape[1] else img
        ok, data = cv2.imencode(".png", scaled, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        if ok and len(data) <= MAX_BYTES:
            target.write_bytes(data.tobytes())
            return len(data)
        width = int(width * 0.85)


def screenshot(page: Path, target: Path) -> bool:
    """Render ``page`` with headless chromium into ``target``; False when chromium is missing."""
    browser = shutil.which("chromium")
    if browser is None:
        return False
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                        "--disable-background-networking", "--disable-component-update", "--disable-sync",
                        f"--user-data-dir={profile}", "--window-size=1280,900", f"--screenshot={target}",
                        page.as_uri()], check=True, capture_output=True, timeout=120)
    return True


def real_pictures(tmp: Path) -> None:
    """Render :data:`REAL` (input above result, textured) when ../shared/data is present."""
    from synthkit.io.assets import load_asset
    from synthkit.preview import Appearance, before_after_png
    from synthkit.runner import run_config

    if not SHARED.is_dir():
        print(f"{SHARED} not present: real-model pictures kept as they are")
        return
    for name, (text, source, result) in REAL.items():
        config = tmp / f"{name}.yaml"
        config.write_text(text)
        run_config(config, out_dir=tmp / name, show_progress=False)
        before, after = load_asset(SHARED / source), load_asset(tmp / name / result)
        raw = tmp / f"{name}-raw.png"
        before_after_png(raw, *[(a.V, a.F, Appearance.of(a, like_input=True)) for a in (before, after)], size=320)
        size = fitted_png(raw, IMAGES / f"{name}.png")
        print(f"{name}: -> docs/images/{name}.png ({size / 1000:.0f} KB)")


def main() -> int:
    from synthkit.review import write_review
    from synthkit.runner import run_config

    IMAGES.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, (config, shown) in PICTURES.items():
            out = Path(tmp) / name
            report = run_config(ROOT / config, out_dir=out, show_progress=False)
            size = fitted_png(out / (shown or report["preview"]), IMAGES / f"{name}.png")
            print(f"{name}: {config} -> docs/images/{name}.png ({size / 1000:.0f} KB)")
        index = write_review(Path(tmp))
        raw = Path(tmp) / "review-raw.png"
        if screenshot(index, raw):
            size = fitted_png(raw, IMAGES / "review.png")
            print(f"review page -> docs/images/review.png ({size / 1000:.0f} KB)")
        else:
            print("chromium not installed: docs/images/review.png not rendered")
        real_pictures(Path(tmp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
