"""Every code block in README.md, docs/*.md and examples/**/README.md runs as written.

A block's kind is its fence's info string:

* ``bash`` / ``sh`` / ``shell``: run with ``bash -euo pipefail`` from the root of a temporary copy
  of the repository (one copy per Markdown file, so a block may use files that earlier blocks of
  the same file wrote; the shipped sample recordings are there), with this interpreter's ``efam``
  and ``python`` first on PATH;
* ``python`` / ``py``: run by this interpreter in a fresh process from that root (self-contained);
* ``xml``: a whole ``<mujoco>`` model is compiled by MuJoCo (with efam.muscle registered); a
  fragment (anything else) must be well-formed XML;
* ``json``: must parse;
* ``text``, ``output``, ``console``, anything else and no info string: shown, not run.

A block whose fence is directly preceded by ``<!-- docs-test: skip REASON -->`` is not run (the
reason is required; use it for the install and test commands, which CI runs itself). A failure
names the file and the line of the block's opening fence.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
RUN_BASH = ("bash", "sh", "shell")
RUN_PYTHON = ("python", "py", "python3")
SKIP = re.compile(r"<!--\s*docs-test:\s*skip\b\s*:?\s*(?P<reason>.*?)\s*-->")
TIMEOUT_S = 300
IGNORED = ("efam_mujoco", ".git", ".venv*", "__pycache__", "*.egg-info", "build", "dist", ".pytest_cache", ".ruff_cache",
           "efam_demo", "out", "*.so")  # fmt: skip


@dataclass(frozen=True)
class Block:
    """One fenced code block: where it is, its kind and its text."""

    file: Path
    line: int  # 1-based line of the opening fence
    kind: str
    text: str
    skip_reason: str | None

    @property
    def where(self) -> str:
        """``file:line`` relative to the repository, for messages and test ids."""
        return f"{self.file.relative_to(REPO)}:{self.line}"


def markdown_files() -> list[Path]:
    """The documents whose blocks are tested."""
    files = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    files += sorted(p for p in (REPO / "examples").rglob("README.md"))
    return [f for f in files if f.is_file()]


def blocks_of(path: Path) -> list[Block]:
    """The fenced blocks of one Markdown file (``` or ~~~ fences; nested fences are not used)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        match = re.match(r"^\s*(```+|~~~+)\s*([^\s`]*)", lines[i])
        if not match:
            i += 1
            continue
        fence, kind, start = match.group(1), match.group(2).lower(), i
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            j += 1
        if j == len(lines):
            raise AssertionError(f"{path.relative_to(REPO)}:{start + 1}: unclosed code fence")
        previous = lines[start - 1] if start > 0 else ""
        skip = SKIP.search(previous)
        if skip and not skip.group("reason"):
            raise AssertionError(f"{path.relative_to(REPO)}:{start}: docs-test skip without a reason")
        out.append(Block(path, start + 1, kind, "\n".join(lines[start + 1 : j]) + "\n",
                         skip.group("reason") if skip else None))  # fmt: skip
        i = j + 1
    return out


ALL_BLOCKS = [block for path in markdown_files() for block in blocks_of(path)]
RUNNABLE = [b for b in ALL_BLOCKS if b.kind in RUN_BASH + RUN_PYTHON + ("xml", "json") and not b.skip_reason]


_workspaces: dict[Path, Path] = {}


@pytest.fixture(scope="session")
def workspace_root(tmp_path_factory) -> Path:
    """Where the per-file copies of the repository go."""
    return tmp_path_factory.mktemp("docs")


def workspace(root: Path, block: Block) -> Path:
    """The temporary copy of the repository for ``block``'s Markdown file (made once per file)."""
    if block.file not in _workspaces:
        target = root / block.file.relative_to(REPO).as_posix().replace("/", "__")
        shutil.copytree(REPO, target, ignore=shutil.ignore_patterns(*IGNORED), symlinks=True)
        # the package itself is linked, not copied: `python -c` imports it from the current
        # directory, and it must be the one under test, with its compiled plugin
        (target / "efam_mujoco").symlink_to(REPO / "efam_mujoco", target_is_directory=True)
        _workspaces[block.file] = target
    return _workspaces[block.file]


def environment() -> dict[str, str]:
    """This interpreter's scripts first on PATH; no progress bars, no display, no shared data."""
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.update(MPLBACKEND="Agg", EFAM_PROGRESS="0", PYTHONDONTWRITEBYTECODE="1")
    for name in ("EFAM_SHARED_DIR", "PYTHONPATH", "DISPLAY"):
        env.pop(name, None)
    return env


def failure(block: Block, what: str, process: subprocess.CompletedProcess | None = None) -> str:
    """A message that names the block and shows its text and the end of its output."""
    text = "\n".join(f"    {line}" for line in block.text.rstrip().splitlines())
    message = f"{block.where}: {block.kind} block {what}\n  block:\n{text}\n"
    if process is not None:
        tail = (process.stdout + process.stderr).strip().splitlines()[-25:]
        message += "  output (last lines):\n" + "\n".join(f"    {line}" for line in tail)
    return message


def run_process(block: Block, command: list[str], cwd: Path) -> None:
    try:
        process = subprocess.run(command, cwd=cwd, env=environment(), capture_output=True, text=True,
                                 timeout=TIMEOUT_S)  # fmt: skip
    except subprocess.TimeoutExpired:
        pytest.fail(failure(block, f"did not finish in {TIMEOUT_S} s"), pytrace=False)
    if process.returncode != 0:
        pytest.fail(failure(block, f"failed (exit {process.returncode})", process), pytrace=False)


def check_xml(block: Block) -> None:
    text = block.text.strip()
    if text.startswith("<mujoco"):
        import mujoco

        import efam_mujoco  # noqa: F401  (registers efam.muscle)

        try:
            mujoco.MjModel.from_xml_string(text)
        except ValueError as err:
            pytest.fail(failure(block, f"does not compile in MuJoCo: {err}"), pytrace=False)
        return
    try:
        ElementTree.fromstring(f"<fragment>{text}</fragment>")
    except ElementTree.ParseError as err:
        pytest.fail(failure(block, f"is not well-formed XML: {err}"), pytrace=False)


@pytest.mark.parametrize("block", RUNNABLE, ids=lambda b: f"{b.where}-{b.kind}")
def test_code_block_runs_as_written(block: Block, workspace_root: Path) -> None:
    if block.kind in RUN_BASH:
        if re.search(r"\bpip\s+install\b|\bpytest\b", block.text):  # would reinstall into this venv
            pytest.fail(f"{block.where}: a block that installs or runs the tests needs a "
                        "`<!-- docs-test: skip REASON -->` line before its fence", pytrace=False)  # fmt: skip
        cwd = workspace(workspace_root, block)
        run_process(block, ["bash", "-euo", "pipefail", "-c", block.text], cwd)
    elif block.kind in RUN_PYTHON:
        cwd = workspace(workspace_root, block)
        run_process(block, [sys.executable, "-c", block.text], cwd)
    elif block.kind == "xml":
        check_xml(block)
    else:
        try:
            json.loads(block.text)
        except json.JSONDecodeError as err:
            pytest.fail(failure(block, f"is not valid JSON: {err}"), pytrace=False)


def test_the_documents_have_runnable_blocks_and_reasons_for_skips():
    files = {b.file.name for b in RUNNABLE}
    assert "README.md" in files and len(RUNNABLE) >= 5, [b.where for b in RUNNABLE]
    assert all(b.skip_reason for b in ALL_BLOCKS if b.skip_reason is not None)


def test_the_block_parser_finds_kinds_lines_and_skips(tmp_path):
    doc = tmp_path / "doc.md"
    doc.write_text("# t\n\n```bash\necho hi\n```\n<!-- docs-test: skip needs a GPU -->\n```python\nx\n```\n"
                   "```\nplain\n```\n")  # fmt: skip
    global REPO
    saved, REPO = REPO, tmp_path
    try:
        found = blocks_of(doc)
    finally:
        REPO = saved
    assert [(b.line, b.kind, b.skip_reason) for b in found] == [
        (3, "bash", None), (7, "python", "needs a GPU"), (10, "", None),
    ]  # fmt: skip
    assert found[0].text == "echo hi\n"
