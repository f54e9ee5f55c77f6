"""The env card and the protocol document name everything the server announces, so they cannot drift."""

import pytest

from conftest import PROJECT_ROOT
from punch_trainer.sim.server import TrainingServer

pytestmark = pytest.mark.godot


def test_env_card_and_protocol_doc_cover_the_spec():
    env_card = (PROJECT_ROOT / "docs" / "env.md").read_text()
    protocol = (PROJECT_ROOT / "docs" / "protocol.md").read_text()
    with TrainingServer(1) as server:
        info = server.info
    for name in info.action_names + info.observation_names:
        assert name in env_card, f"docs/env.md does not mention {name}"
    for name in info.feature_names:
        stem = name.rstrip("xyz").rstrip("_") if name[-2:] in ("_x", "_y", "_z") else name
        assert stem in env_card, f"docs/env.md does not mention {name}"
    assert f"{len(info.feature_names)} floats per physics frame" in env_card
    assert "F per-frame features" in protocol and f"{len(info.feature_names)} in spec" in protocol
    assert f"spec version {info.spec_version}" in env_card
