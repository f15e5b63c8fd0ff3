"""A review page for a folder of runs: ``OUT_ROOT/index.html``, self-contained and static.

``write_review(out_root)`` reads ``batch.json`` (when a batch wrote one) and every run folder's
``report.json`` and writes:

- ``index.html``: a card per run (its summary preview as a thumbnail, status, headline metrics,
  the failure line) and a table of every run, sortable by any column and filterable by status
  and text, by a few lines of inline JavaScript (no network, no server: open the file);
- ``review/thumbs/<run>.jpg``: thumbnails, written once (again only when the preview is newer),
  loaded lazily, so a page of 1,000 runs opens at once;
- ``review/runs/<run>.html``: a page per run with every preview, the error, the config and the
  report.

Links are relative, so the folder can be moved or served as it is. Refused and failed runs
appear too: a refused run has its folder and report; a failed run without a folder shows its
``batch.json`` row.
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2

from synthkit.io.atomic import write_bytes_atomic, write_text_atomic
from synthkit.summary import headline, summary_preview

__all__ = ["write_review", "collect_runs", "RunEntry", "REVIEW_DIR", "THUMB_SIZE", "GENERATOR"]

GENERATOR = '<meta name="generator" content="synthkit review">'
"""Marks an ``index.html`` synthkit wrote (another one is never replaced)."""

REVIEW_DIR = "review"
THUMB_SIZE = 240
"""Longest side of a thumbnail, in pixels."""

@dataclass
class RunEntry:
    """One run on the page: its name, folder (relative to the root, or None), status, the failure
    line, method, headline metrics, summary preview and every preview (relative to the folder)."""

    name: str
    folder: str | None
    status: str
    method: str = ""
    error: str | None = None
    metrics: dict = field(default_factory=dict)
    preview: str | None = None
    previews: list = field(default_factory=list)
    report: dict | None = None


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _entry_of_folder(root: Path, folder: Path, row: dict | None) -> RunEntry:
    report = _read_json(folder / "report.json") or {}
    outputs = report.get("outputs", {})
    status = report.get("status", row["status"] if row else "unknown")
    if row and row.get("status") not in (None, "ok", "degraded") and status == "ok":
        status = row["status"]
    method = report.get("method")
    return RunEntry(name=folder.name, folder=folder.relative_to(root).as_posix(), status=status,
                    method=method or "", error=report.get("error") or (row or {}).get("error"),
                    metrics=headline(report.get("metrics", {}), method), preview=summary_preview(outputs, method),
                    previews=[v for v in outputs.values() if str(v).lower().endswith(".png")], report=report)


def collect_runs(root: Path | str) -> list[RunEntry]:
    """Every run under ``root``: the rows of ``batch.json`` in order (with their folders when they
    exist), then any other folder holding a ``report.json``, by name."""
    root = Path(root)
    rows = (_read_json(root / "batch.json") or {}).get("runs", [])
    entries, seen = [], set()
    for row in rows:
        out = row.get("out")
        folder = Path(out) if out else None
        if folder is not None and not folder.is_absolute():
            folder = Path(os.path.abspath(folder))
        if folder is not None and not (folder / "report.json").is_file():  # written from another folder
            folder = root.absolute() / folder.name
        if folder is not None and (folder / "report.json").is_file() and folder.parent == root.absolute():
            entries.append(_entry_of_folder(root.absolute(), folder, row))
            seen.add(folder.name)
        else:
            name = Path(row.get("config", "run")).stem
            entries.append(RunEntry(name=name, folder=None, status=row.get("status", "failed"),
                                    error=row.get("error"), metrics=row.get("metrics") or {}))
    for folder in sorted(p for p in root.iterdir() if p.is_dir() and p.name not in seen and p.name != REVIEW_DIR):
        if (folder / "report.json").is_file():
            entries.append(_entry_of_folder(root.absolute(), folder.absolute(), None))
    return entries


def _thumbnail(root: Path, entry: RunEntry) -> str | None:
    """Write (once; again when the preview is newer) the entry's thumbnail; its path relative to root."""
    if entry.folder is None or entry.preview is None:
        return None
    source = root / entry.folder / entry.preview
    if not source.is_file():
        return None
    rel = f"{REVIEW_DIR}/thumbs/{entry.name}.jpg"
    target = root / rel
    if target.is_file() and target.stat().st_mtime >= source.stat().st_mtime:
        return rel
    img = cv2.imread(str(source), cv2.IMREAD_COLOR)
    if img is None:
        return None
    scale = THUMB_SIZE / max(img.shape[:2])
    if scale < 1:
        img = cv2.resize(img, (max(1, round(img.shape[1] * scale)), max(1, round(img.shape[0] * scale))),
                         interpolation=cv2.INTER_AREA)
    target.parent.mkdir(parents=True, exist_ok=True)
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])
    if not ok:
        return None
    write_bytes_atomic(target, data.tobytes())
    return rel


_STYLE = """
body{font:14px system-ui,sans-serif;margin:16px;color:#222;background:#fafafa}
h1{font-size:20px;margin:0 0 8px} .bar{margin:8px 0 12px} .bar *{margin-right:8px}
.cards{display:grid;grid-template-columns:repeat(auto-fill,minmax(250px,1fr));gap:10px}
.card{display:block;background:#fff;border:1px solid #ddd;border-radius:6px;padding:6px;color:inherit;
text-decoration:none}
.card img{width:100%;height:180px;object-fit:contain;background:#f0f0f0;display:block}
.noimg{height:180px;display:flex;align-items:center;justify-content:center;background:#eee;color:#888}
.name{font-weight:600;margin-top:4px;word-break:break-all} .m{font-size:12px;color:#555}
.err{font-size:12px;color:#a00;word-break:break-word}
.st{display:inline-block;padding:0 6px;border-radius:8px;font-size:12px;color:#fff}
.st-ok{background:#2a7} .st-degraded,.st-partial{background:#d80} .st-refused{background:#888}
.st-failed,.st-skipped,.st-unknown{background:#c33}
table{border-collapse:collapse;margin-top:16px;background:#fff} th,td{border:1px solid #ddd;padding:3px 6px}
th{cursor:pointer;background:#eee} pre{background:#fff;border:1px solid #ddd;padding:8px;overflow:auto}
.previews img{max-width:100%;border:1px solid #ddd;margin:4px 0}
"""

_SCRIPT = """
function apply(){var s=document.getElementById('status').value,q=document.getElementById('q').value.toLowerCase();
document.querySelectorAll('[data-status]').forEach(function(e){var ok=(!s||e.dataset.status==s)&&
(!q||e.dataset.text.indexOf(q)>=0);e.style.display=ok?'':'none';});}
function sortBy(k){var b=document.querySelector('#runs tbody'),r=Array.from(b.rows),
d=b.dataset.key==k&&b.dataset.dir=='1'?-1:1;b.dataset.key=k;b.dataset.dir=d;
r.sort(function(x,y){var a=x.cells[k].dataset.v,c=y.cells[k].dataset.v,na=parseFloat(a),nc=parseFloat(c);
if(!isNaN(na)&&!isNaN(nc))return d*(na-nc);return d*a.localeCompare(c);});r.forEach(function(x){b.appendChild(x);});}
"""


def _fmt(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _card(entry: RunEntry, thumb: str | None) -> str:
    e = html.escape
    image = (f'<img loading="lazy" src="{e(thumb)}" alt="{e(entry.name)}">' if thumb
             else '<div class="noimg">no preview</div>')
    metrics = ", ".join(f"{e(k)}={e(_fmt(v))}" for k, v in entry.metrics.items())
    error = f'<div class="err">{e(entry.error)}</div>' if entry.error else ""
    text = e(f"{entry.name} {entry.method} {entry.status} {entry.error or ''}".lower())
    return (f'<a class="card" href="{REVIEW_DIR}/runs/{e(entry.name)}.html" data-status="{e(entry.status)}" '
            f'data-text="{text}">{image}<div class="name">{e(entry.name)}</div>'
            f'<span class="st st-{e(entry.status)}">{e(entry.status)}</span> <span class="m">{e(entry.method)}</span>'
            f'<div class="m">{metrics}</div>{error}</a>')


def _table(entries: list[RunEntry]) -> str:
    e = html.escape
    keys = sorted({k for entry in entries for k in entry.metrics})
    head = ["run", "method", "status", *keys, "error"]
    rows = []
    for entry in entries:
        cells = [entry.name, entry.method, entry.status, *[entry.metrics.get(k, "") for k in keys], entry.error or ""]
        text = e(f"{entry.name} {entry.method} {entry.status} {entry.error or ''}".lower())
        tds = "".join(f'<td data-v="{e(str(c))}">{e(_fmt(c))}</td>' for c in cells)
        rows.append(f'<tr data-status="{e(entry.status)}" data-text="{text}">{tds}</tr>')
    ths = "".join(f'<th onclick="sortBy({i})">{e(h)}</th>' for i, h in enumerate(head))
    return f'<table id="runs"><thead><tr>{ths}</tr></thead><tbody>{"".join(rows)}</tbody></table>'


def _index(entries: list[RunEntry], thumbs: list) -> str:
    e = html.escape
    counts = {}
    for entry in entries:
        counts[entry.status] = counts.get(entry.status, 0) + 1
    options = "".join(f'<option value="{e(s)}">{e(s)} ({n})</option>' for s, n in sorted(counts.items()))
    cards = "".join(_card(entry, thumb) for entry, thumb in zip(entries, thumbs, strict=True))
    summary = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
    return (f'<!DOCTYPE html><html><head><meta charset="utf-8">{GENERATOR}<title>synthkit runs</title>'
            f"<style>{_STYLE}</style></head><body><h1>synthkit: {len(entries)} runs ({e(summary)})</h1>"
            f'<div class="bar"><select id="status" onchange="apply()"><option value="">every status</option>'
            f'{options}</select><input id="q" placeholder="filter" oninput="apply()"></div>'
            f'<div class="cards">{cards}</div>{_table(entries)}<script>{_SCRIPT}</script></body></html>\n')


def _run_page(entry: RunEntry) -> str:
    e = html.escape
    up = "../.."
    images = "".join(f'<h3>{e(p)}</h3><img loading="lazy" src="{up}/{e(entry.folder)}/{e(p)}" alt="{e(p)}">'
                     for p in entry.previews) if entry.folder else "<p>no output folder</p>"
    report = entry.report or {}
    config = json.dumps(report.get("config", {}), indent=2)
    body = json.dumps({k: v for k, v in report.items() if k != "config"}, indent=2)
    error = f'<p class="err">{e(entry.error)}</p>' if entry.error else ""
    folder = f'<a href="{up}/{e(entry.folder)}/">{e(entry.folder)}/</a>' if entry.folder else ""
    return (f'<!DOCTYPE html><html><head><meta charset="utf-8"><title>{e(entry.name)}</title>'
            f'<style>{_STYLE}</style></head><body><p><a href="{up}/index.html">all runs</a></p>'
            f'<h1>{e(entry.name)} <span class="st st-{e(entry.status)}">{e(entry.status)}</span></h1>'
            f'<p>{e(entry.method)} {folder}</p>{error}<div class="previews">{images}</div>'
            f"<h2>config</h2><pre>{e(config)}</pre><h2>report</h2><pre>{e(body)}</pre></body></html>\n")


def write_review(root: Path | str) -> Path:
    """Write ``index.html``, the thumbnails and a page per run into ``root`` (module docstring);
    return the index's path. Only ``index.html`` and files under ``review/`` are written; an
    ``index.html`` that synthkit did not write is never replaced (ValueError)."""
    root = Path(root)
    index = root / "index.html"
    if index.is_file() and GENERATOR not in index.read_text(encoding="utf-8", errors="replace")[:2000]:
        raise ValueError(f"{index} exists and was not written by synthkit; not replaced")
    entries = collect_runs(root)
    names = [entry.name for entry in entries]
    for i, entry in enumerate(entries):  # failed runs of two configs with one stem: keep pages apart
        if names.count(entry.name) > 1:
            entry.name = f"{entry.name}-{i}"
    thumbs = [_thumbnail(root, entry) for entry in entries]
    pages = root / REVIEW_DIR / "runs"
    pages.mkdir(parents=True, exist_ok=True)
    for entry in entries:
        write_text_atomic(pages / f"{entry.name}.html", _run_page(entry))
    write_text_atomic(index, _index(entries, thumbs))
    return index
