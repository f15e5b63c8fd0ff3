"""Regenerate the pictures of the README and docs/ from bundled samples (``make pictures``).

Each picture is the summary preview of one bundled config, run in a temporary folder, scaled to
at most :data:`MAX_WIDTH` pixels wide and written to ``docs/images/<name>.png`` under
:data:`MAX_BYTES` (scaled down further until it fits). With Debian's chromium installed, the review
page of those runs is rendered too (``docs/images/review.png``).

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
    "retarget": "configs/retarget/facade.yaml",
    "petri-synth": "configs/petri-synth/building_ring.yaml",
    "symmetry-texture": "configs/symmetry-texture/transfer.yaml",
    "surface-by-numbers": "configs/surface-by-numbers/painted.yaml",
    "surface-by-numbers-transfer": "configs/surface-by-numbers/transfer-stripes.yaml",
    "reshape": "configs/reshape/house-link.yaml",
}
"""Picture name -> the bundled config whose summary preview it shows."""


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


def main() -> int:
    from synthkit.review import write_review
    from synthkit.runner import run_config

    IMAGES.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, config in PICTURES.items():
            out = Path(tmp) / name
            report = run_config(ROOT / config, out_dir=out, show_progress=False)
            size = fitted_png(out / report["preview"], IMAGES / f"{name}.png")
            print(f"{name}: {config} -> docs/images/{name}.png ({size / 1000:.0f} KB)")
        index = write_review(Path(tmp))
        raw = Path(tmp) / "review-raw.png"
        if screenshot(index, raw):
            size = fitted_png(raw, IMAGES / "review.png")
            print(f"review page -> docs/images/review.png ({size / 1000:.0f} KB)")
        else:
            print("chromium not installed: docs/images/review.png not rendered")
    return 0


if __name__ == "__main__":
    sys.exit(main())
