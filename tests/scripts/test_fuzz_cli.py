"""`lens-lights fuzz` as a user meets it: its help lists its options, bad counts
are refused, and a run prints nothing per correctly refused input, only a summary."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.blender  # every 200th input goes through Blender's importer

ROOT = Path(__file__).resolve().parents[2]
CLI = ROOT / "scripts" / "cli.py"


def run_cli(*args, timeout=300):
    return subprocess.run(
        [sys.executable, str(CLI), *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def test_fuzz_help_lists_its_options():
    result = run_cli("fuzz", "--help")
    assert result.returncode == 0, result.stderr
    assert "usage: lens-lights fuzz" in result.stdout
    assert "--count N" in result.stdout and "--seed" in result.stdout


@pytest.mark.parametrize("count", ["-5", "0", "many"])
def test_fuzz_refuses_a_bad_count(count):
    result = run_cli("fuzz", "--count", count)
    assert result.returncode == 2
    assert f"expected a positive integer, got '{count}'" in result.stderr
    assert "inputs in" not in result.stdout


def test_fuzz_run_prints_only_a_summary():
    """401 inputs: 3 through Blender's importer (refused ones made Blender print
    "Error: …" lines), 9 through the CLI; nearly all are refused, as they should be."""
    result = run_cli("fuzz", "--count", "401", "--seed", "3")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Error" not in result.stdout + result.stderr
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1, lines
    m = re.fullmatch(
        r"fuzz: 401 inputs in [\d.]+ s: (\d+) parsed, (\d+) refused as expected "
        r"\(an error with a line number\), 0 failure\(s\)",
        lines[0],
    )
    assert m, lines[0]
    parsed, refused = int(m[1]), int(m[2])
    assert parsed + refused == 401 and refused > 300
