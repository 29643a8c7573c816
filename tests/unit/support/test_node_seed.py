"""tests/hil/scenario_support.py's node_seed: a fresh fault seed for each scenario's node, or the one to replay."""

from __future__ import annotations

import pytest

from tests.hil.scenario_support import NODE_SEED_ENV, node_seed


def test_each_node_gets_a_fresh_seed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(NODE_SEED_ENV, raising=False)
    seeds = [node_seed() for _ in range(8)]
    assert len(set(seeds)) == len(seeds), seeds  # 8 draws from 2**31: a repeat has odds below 1e-8
    assert all(0 <= seed < 2**31 for seed in seeds)


@pytest.mark.parametrize("text", ["42", " 42\n"])
def test_the_environment_replays_a_seed(monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    monkeypatch.setenv(NODE_SEED_ENV, text)
    assert [node_seed(), node_seed()] == [42, 42]


@pytest.mark.parametrize(("text", "says"), [("forty-two", "'forty-two' is not an integer"), ("-3", "-3 is negative")])
def test_a_bad_seed_in_the_environment_is_named(monkeypatch: pytest.MonkeyPatch, text: str, says: str) -> None:
    monkeypatch.setenv(NODE_SEED_ENV, text)
    with pytest.raises(ValueError, match=NODE_SEED_ENV) as raised:
        node_seed()
    assert says in str(raised.value)
