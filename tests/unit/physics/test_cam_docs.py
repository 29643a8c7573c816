"""docs/model.md#cam-shapes shows the cam comparison exactly as `millctl limits --cam double` prints it."""

from __future__ import annotations

import re
import shlex

import pytest

from millctl.cli import main
from tests.conftest import CONFIG_FILE, REPO

BLOCK = re.compile(r"<!-- output of: millctl (?P<args>[^>]*?) -->\n```text\n(?P<text>.*?)\n```", re.S)
BLOCKS = [(m["args"], m["text"]) for m in BLOCK.finditer((REPO / "docs" / "model.md").read_text(encoding="utf-8"))]


def test_the_docs_hold_the_cam_comparison() -> None:
    assert len(BLOCKS) >= 2 and all("--cam double" in args for args, _ in BLOCKS)


@pytest.mark.parametrize(("args", "text"), BLOCKS, ids=[a for a, _ in BLOCKS])
def test_docs_block_is_the_commands_output(args: str, text: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--config", str(CONFIG_FILE), *shlex.split(args)]) == 0
    assert capsys.readouterr().out.rstrip("\n") == text


def test_double_cam_claim_in_numbers(capsys: pytest.CaptureFixture[str]) -> None:
    """Paper's model: more impacts per revolution, fewer than twice; corrected model: none more."""
    import json

    assert main(["--config", str(CONFIG_FILE), "limits", "--cam", "double", "--vib-rpm", "400", "800", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["result"]["cams"]
    for row in rows:
        ratio_paper = row["p_paper_double"] / row["p_paper_single"]
        assert 1.0 < ratio_paper < 2.0
        assert row["p_corrected_double"] / row["p_corrected_single"] == pytest.approx(1.0, abs=0.01)
        assert row["limit_rotary_double_rpm"] > row["limit_rotary_single_rpm"]  # printed eq. 9 moves up
