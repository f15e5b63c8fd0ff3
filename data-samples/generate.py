"""Write every bundled sample into this folder and record SHA256SUMS (``make samples``).

    python data-samples/generate.py           # regenerate here and rewrite SHA256SUMS
    python data-samples/generate.py --check   # regenerate into a temporary folder, compare sums

Each sample set is a module of :mod:`synthkit.samples` with ``generate(out_dir) -> list[Path]``.
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SUMS = "SHA256SUMS"
SKIP = {"generate.py", SUMS}


def generate_all(out_dir: Path) -> list[Path]:
    """Run every sample set's generator into ``out_dir``; return the files written."""
    from synthkit.samples import SAMPLE_SETS

    written: list[Path] = []
    for name in SAMPLE_SETS:
        module = importlib.import_module(f"synthkit.samples.{name}")
        written.extend(module.generate(out_dir))
    return written


def checksums(folder: Path) -> dict[str, str]:
    """SHA-256 of every sample file under ``folder`` (relative path -> hex digest)."""
    sums = {}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder).as_posix()
        if path.is_file() and rel not in SKIP and "__pycache__" not in rel:
            sums[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return sums


def read_sums(path: Path) -> dict[str, str]:
    """Parse a SHA256SUMS file (``<hex>  <name>`` per line)."""
    sums = {}
    for line in path.read_text().splitlines():
        digest, _, name = line.partition("  ")
        sums[name] = digest
    return sums


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="regenerate elsewhere and compare with SHA256SUMS")
    args = parser.parse_args()
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            generate_all(Path(tmp))
            fresh = checksums(Path(tmp))
        recorded = read_sums(HERE / SUMS)
        bad = sorted(k for k in fresh.keys() | recorded.keys() if fresh.get(k) != recorded.get(k))
        for name in bad:
            print(f"differs: {name}", file=sys.stderr)
        print(f"{len(fresh)} files, {len(bad)} differ", file=sys.stderr)
        return 1 if bad else 0
    generate_all(HERE)
    sums = checksums(HERE)
    (HERE / SUMS).write_text("".join(f"{digest}  {name}\n" for name, digest in sums.items()))
    total = sum((HERE / name).stat().st_size for name in sums)
    print(f"wrote {len(sums)} files, {total / 1e6:.2f} MB", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
