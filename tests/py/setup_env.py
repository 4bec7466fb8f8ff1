#!/usr/bin/env python3
"""Makes the Python environment the interop tests use: a virtual environment under the cargo
target directory (`target/py`, or `$CARGO_TARGET_DIR/py`) holding tests/py/requirements.txt.

Usage:
    python3 tests/py/setup_env.py

Works on a stock Ubuntu 24.04 or Debian 12 with nothing but `python3`: their system
interpreter refuses `pip install` (PEP 668, "externally-managed-environment") and ships
neither pip nor ensurepip. So:
  - with `uv` on the PATH, `uv venv` and `uv pip install` do everything;
  - otherwise the standard library's `venv` makes the environment (without pip when
    ensurepip is missing), and pip is bootstrapped from its wheel on the package index
    (`$PIP_INDEX_URL`, default https://pypi.org/simple), checked against the index's sha256,
    then installs the requirements.
Nothing is installed outside the target directory. A second run with unchanged
requirements does nothing. The tests find the interpreter at `<target>/py/bin/python`
(`$CHRONOTOPE_PYTHON` overrides it).
"""

from __future__ import annotations

import hashlib
import html.parser
import os
import re
import shutil
import subprocess
import sys
import tempfile
import urllib.parse
import urllib.request
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
REQUIREMENTS = ROOT / "tests" / "py" / "requirements.txt"


def target_dir() -> Path:
    t = os.environ.get("CARGO_TARGET_DIR")
    return Path(t) if t else ROOT / "target"


def say(msg: str) -> None:
    print(f"setup_env: {msg}", file=sys.stderr, flush=True)


def run(*cmd: str | Path) -> None:
    say(" ".join(str(c) for c in cmd))
    subprocess.run([str(c) for c in cmd], check=True)


class Links(html.parser.HTMLParser):
    """The links of a PEP 503 simple index page: (file name, url, requires-python)."""

    def __init__(self) -> None:
        super().__init__()
        self.links: list[tuple[str, str, str]] = []
        self._href: str | None = None
        self._requires = ""

    def handle_starttag(self, tag, attrs):
        if tag == "a":
            a = dict(attrs)
            self._href = a.get("href")
            self._requires = a.get("data-requires-python") or ""

    def handle_data(self, data):
        if self._href is not None:
            self.links.append((data.strip(), self._href, self._requires))
            self._href = None


def python_ok(spec: str) -> bool:
    """Whether this interpreter satisfies a simple requires-python (">=3.9", ">=3.8,<4")."""
    here = sys.version_info[:2]
    for part in filter(None, (p.strip() for p in spec.split(","))):
        m = re.fullmatch(r"(>=|>|<=|<|==|!=)\s*(\d+)(?:\.(\d+))?(?:\.\*|\.\d+)*", part)
        if not m:
            continue
        op, major, minor = m.group(1), int(m.group(2)), int(m.group(3) or 0)
        v = (major, minor)
        if not {
            ">=": here >= v,
            ">": here > v,
            "<=": here <= v,
            "<": here < v,
            "==": here[: 1 if m.group(3) is None else 2] == v[: 1 if m.group(3) is None else 2],
            "!=": here != v,
        }[op]:
            return False
    return True


def bootstrap_pip(python: Path) -> None:
    """Installs pip into the environment from its wheel on the package index."""
    index = os.environ.get("PIP_INDEX_URL", "https://pypi.org/simple").rstrip("/")
    page_url = f"{index}/pip/"
    say(f"no pip and no ensurepip: fetching pip's wheel from {page_url}")
    with urllib.request.urlopen(page_url, timeout=120) as r:
        page = r.read().decode("utf-8", "replace")
    parser = Links()
    parser.feed(page)
    wheels = []
    for name, href, requires in parser.links:
        m = re.fullmatch(r"pip-(\d+(?:\.\d+)*)-py3-none-any\.whl", name)
        if m and "#sha256=" in href and python_ok(requires):
            version = tuple(int(x) for x in m.group(1).split("."))
            wheels.append((version, name, href))
    if not wheels:
        raise SystemExit(f"setup_env: no pip wheel for this Python on {page_url}")
    _, name, href = max(wheels)
    url, digest = href.split("#sha256=", 1)
    url = urllib.parse.urljoin(page_url, url)
    with tempfile.TemporaryDirectory() as tmp:
        wheel = Path(tmp) / name
        with urllib.request.urlopen(url, timeout=300) as r:
            data = r.read()
        if hashlib.sha256(data).hexdigest() != digest:
            raise SystemExit(f"setup_env: {name} does not match the index's sha256")
        wheel.write_bytes(data)
        # A pip wheel runs from itself: `python pip.whl/pip install pip.whl`.
        run(python, f"{wheel}/pip", "install", "--quiet", "--no-index", str(wheel))


def main() -> int:
    env_dir = target_dir() / "py"
    python = env_dir / "bin" / "python"
    stamp = env_dir / "requirements.sha256"
    want = hashlib.sha256(REQUIREMENTS.read_bytes()).hexdigest()
    if python.exists() and stamp.exists() and stamp.read_text().strip() == want:
        say(f"{env_dir} is up to date")
        return 0
    uv = shutil.which("uv")
    if uv:
        if not python.exists():
            run(uv, "venv", "--quiet", "--python", sys.executable, env_dir)
        run(uv, "pip", "install", "--quiet", "--python", python, "-r", REQUIREMENTS)
    else:
        if not python.exists():
            try:
                import ensurepip  # noqa: F401

                has_ensurepip = True
            except ImportError:
                has_ensurepip = False
            say(f"creating {env_dir} (pip from ensurepip: {has_ensurepip})")
            venv.EnvBuilder(with_pip=has_ensurepip, clear=True).create(env_dir)
        if subprocess.run([str(python), "-m", "pip", "--version"], capture_output=True).returncode:
            bootstrap_pip(python)
        run(
            python,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "-r",
            REQUIREMENTS,
        )
    stamp.write_text(want + "\n")
    say(f"ready: {python}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
