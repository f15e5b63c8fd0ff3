"""The review page of a folder of runs: parsed as HTML, and drawn by a real browser."""

import json
import os
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from synthkit.io.images import load_image, save_image
from synthkit.review import REVIEW_DIR, write_review

COLOURS = {"red": (1.0, 0.0, 0.0), "green": (0.0, 1.0, 0.0), "blue": (0.0, 0.0, 1.0)}


class _Links(HTMLParser):
    """Collects the cards (``a.card``), images and links of a page."""

    def __init__(self):
        super().__init__()
        self.cards, self.images, self.links = [], [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "a" and a.get("class") == "card":
            self.cards.append(a)
        if tag == "img":
            self.images.append(a)
        if tag == "a" and "href" in a:
            self.links.append(a["href"])


def _run_folder(root: Path, name: str, colour, status="ok", error=None):
    folder = root / name
    folder.mkdir(parents=True)
    save_image(folder / "comparison.png", np.broadcast_to(np.array(colour, np.float32), (320, 480, 3)).copy())
    save_image(folder / "other.png", np.zeros((8, 8), np.float32))
    report = {"method": "retarget", "status": status, "config": {"seed": 0}, "metrics": {"energy": 1.5, "cells": 3},
              "outputs": {"other": "other.png", "comparison": "comparison.png", "report": "report.json"}}
    if error:
        report["error"] = error
    (folder / "report.json").write_text(json.dumps(report))
    return folder


@pytest.fixture
def runs(tmp_path):
    root = tmp_path / "out"
    _run_folder(root, "red", COLOURS["red"])
    _run_folder(root, "green", COLOURS["green"], status="refused", error="green.yaml: refused on purpose")
    _run_folder(root, "blue", COLOURS["blue"])
    rows = [{"config": "red.yaml", "status": "ok", "out": str(root / "red")},
            {"config": "green.yaml", "status": "failed", "out": str(root / "green"), "error": "refused on purpose"},
            {"config": "gone.yaml", "status": "failed", "out": None, "error": "gone.yaml: config file not found"}]
    (root / "batch.json").write_text(json.dumps({"synthkit_batch": "0", "runs": rows}))
    return root


def test_index_has_a_card_per_run_with_its_thumbnail(runs):
    index = write_review(runs)
    page = _Links()
    page.feed(index.read_text())
    assert [c["data-status"] for c in page.cards] == ["ok", "refused", "failed", "ok"]
    thumbs = [img["src"] for img in page.images]
    assert thumbs == [f"{REVIEW_DIR}/thumbs/{n}.jpg" for n in ("red", "green", "blue")]
    assert all(img["loading"] == "lazy" for img in page.images)
    for name, src in zip(("red", "green", "blue"), thumbs, strict=True):
        pixels = load_image(runs / src)
        assert pixels.shape == (160, 240, 3)
        assert np.abs(pixels.mean(axis=(0, 1)) - COLOURS[name]).max() < 0.02
    text = index.read_text()
    assert "gone.yaml: config file not found" in text and "green.yaml: refused on purpose" in text
    assert "http" not in text.replace('content="synthkit review"', "")  # no network


def test_run_pages_link_every_preview_and_the_index(runs):
    write_review(runs)
    page = _Links()
    page.feed((runs / REVIEW_DIR / "runs" / "green.html").read_text())
    pages = runs / REVIEW_DIR / "runs"
    assert sorted(os.path.normpath(pages / img["src"]) for img in page.images) == sorted(
        str(runs / "green" / f) for f in ("comparison.png", "other.png"))
    assert "../../index.html" in page.links


def test_thumbnails_are_written_once(runs):
    write_review(runs)
    thumb = runs / REVIEW_DIR / "thumbs" / "red.jpg"
    stamp = thumb.stat().st_mtime_ns
    write_review(runs)
    assert thumb.stat().st_mtime_ns == stamp


def test_a_foreign_index_is_never_replaced(runs):
    (runs / "index.html").write_text("<html>mine</html>")
    with pytest.raises(ValueError, match="exists and was not written by synthkit"):
        write_review(runs)
    assert (runs / "index.html").read_text() == "<html>mine</html>"


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (make test installs it as root: "
                                             "apt-get install chromium); the page is still checked as HTML")
def test_browser_draws_the_cards_and_their_thumbnails(runs, tmp_path):
    index = write_review(runs)
    shot = tmp_path / "page.png"
    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                    "--disable-background-networking", "--disable-component-update", "--disable-sync",
                    f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1200,900", f"--screenshot={shot}",
                    index.as_uri()], check=True, capture_output=True, timeout=120)
    img = load_image(shot)
    for name, colour in COLOURS.items():
        drawn = (np.abs(img - np.array(colour, np.float32)) < 0.1).all(axis=2).sum()
        assert drawn > 5000, f"the {name} thumbnail is not drawn ({drawn} pixels of its colour)"


def test_rows_written_from_another_folder_find_their_runs(runs, monkeypatch, tmp_path):
    """batch.json rows name their folders as the batch was given them (relative to where it ran);
    the page finds them in OUT_ROOT wherever `synthkit report` runs."""
    rows = json.loads((runs / "batch.json").read_text())
    for row in rows["runs"]:
        if row["out"]:
            row["out"] = f"elsewhere/{Path(row['out']).name}"
    (runs / "batch.json").write_text(json.dumps(rows))
    monkeypatch.chdir(tmp_path)
    page = _Links()
    page.feed(write_review(runs).read_text())
    assert [c["data-status"] for c in page.cards] == ["ok", "refused", "failed", "ok"]
