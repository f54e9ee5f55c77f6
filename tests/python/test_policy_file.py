"""What a policy file carries (punch_trainer/policy_file.py): the metadata keys are punch_core's, named in one
place of the trainer; a required entry that is missing is an error naming it, never a default; the writer's
files read back."""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import numpy as np
import onnx
import pytest

from conftest import PROJECT_ROOT
from punch_trainer import policy_file
from punch_trainer.errors import MissingMetadataError, PolicyFileError
from punch_trainer.learn.export import export_policy
from punch_trainer.learn.policy import ActorCritic
from punch_trainer.learn.reach import ReachVolume
from punch_trainer.pipelines.recipe import TrainStage
from punch_trainer.pipelines.results import shipped_recipes
from punch_trainer.policy_file import (
    ANNOUNCED_KEYS,
    CONTRACT_KEYS,
    REQUIRED_KEYS,
    REQUIRED_METADATA,
    START_LOAD,
    TRAINER_KEYS,
    PolicyMetadata,
    read_entries,
    read_policy_metadata,
)

SHIPPED = sorted((PROJECT_ROOT / "addons" / "punch_controller" / "policies").glob("*.onnx"))
SHIPPED_STRAIGHT = PROJECT_ROOT / "addons" / "punch_controller" / "policies" / "straight.onnx"
TRAINER = PROJECT_ROOT / "trainer" / "punch_trainer"


def rust_contract_source() -> str:
    """punch_core's contract (the file that holds `pub mod keys`, wherever the crate's folders put it)."""
    sources = [path for path in (PROJECT_ROOT / "gdextension").glob("*/src/**/*.rs") if "pub mod keys" in path.read_text()]
    assert len(sources) == 1, sources
    return sources[0].read_text()


def rust_keys() -> dict[str, str]:
    """punch_core's `keys`: constant name -> key, in their order."""
    body = re.search(r"pub mod keys \{(.*?)\n\}", rust_contract_source(), re.S)
    assert body is not None
    return dict(re.findall(r'pub const (\w+): &str = "([^"]+)";', body.group(1)))


def test_the_keys_are_punch_cores():
    source = rust_contract_source()
    keys = rust_keys()
    assert tuple(keys.values()) == CONTRACT_KEYS
    assert {name: getattr(policy_file, name) for name in keys} == keys, "the Python constants are named as Rust's"
    required = re.search(r"pub const REQUIRED_METADATA: \[&str; \d+\] =\s*\[(.*?)\];", source, re.S)
    assert required is not None
    assert tuple(keys[name] for name in re.findall(r"keys::(\w+)", required.group(1))) == REQUIRED_METADATA
    announced = re.search(r"pub fn metadata\(&self\).*?\n    \}", source, re.S)
    assert announced is not None
    assert tuple(keys[name] for name in re.findall(r"keys::(\w+)", announced.group(0))) == ANNOUNCED_KEYS
    assert "ReachVolume::from_metadata" in source and keys["REACH_VOLUME"] in REQUIRED_KEYS
    assert not set(TRAINER_KEYS) & set(CONTRACT_KEYS)


@pytest.mark.godot
def test_a_training_server_announces_the_contract_the_trainer_names():
    from punch_trainer.sim.server import TrainingServer

    with TrainingServer(1) as server:
        announced = server.reset().fields["policy_metadata"]
    assert tuple(sorted(announced)) == tuple(sorted(ANNOUNCED_KEYS))
    assert set(REQUIRED_METADATA) <= set(announced)


def test_no_module_of_the_trainer_spells_a_key_but_policy_file():
    """Every other module names a key by its constant (`policy_file.FRAMES`), so a key is renamed in one place."""
    keys = set(CONTRACT_KEYS) | set(TRAINER_KEYS)
    spelled = sorted(f"{path.relative_to(TRAINER)}: {node.value}" for path in TRAINER.rglob("*.py") if path.name != "policy_file.py"
                     for node in ast.walk(ast.parse(path.read_text()))
                     if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in keys)
    assert spelled == []


@pytest.mark.parametrize("policy", SHIPPED, ids=lambda path: path.name)
def test_the_shipped_policies_read_with_every_entry(policy: Path):
    metadata = read_policy_metadata(policy)
    assert metadata.physics_hz == 120 and metadata.frames % metadata.decision_period == 0
    # The reward its recipe trained it with (a move of one stance's guard is named for its move, not its reward).
    recipe = next(recipe for recipe in shipped_recipes() if recipe.policy.name == policy.name)
    # The last training stage made it (a soup after it mixes stages of one reward and one reach).
    last = [stage for stage in recipe.stages if isinstance(stage, TrainStage)][-1]
    assert last.args["reward"] == metadata.reward and metadata.training_summary is not None and metadata.noise_scale is not None
    # Its reach: the spec's (the straight's, trained from every start), a lead hand's moved forward 0.10 m
    # (punch_core's LEAD_REACH_FORWARD_M), a close move's (a hook's) distances its recipe's `reach_distance`, a move's heights its `reach_height`.
    square = ReachVolume.from_json(read_policy_metadata(SHIPPED_STRAIGHT).reach_volume)
    expected = square.moved_forward(0.10 if recipe.guard == "southpaw" else 0.0)
    if last.args.get("reach_distance"):
        near, far = last.args["reach_distance"]
        expected = dataclasses.replace(expected, distance_m=(near, far))
    if last.args.get("reach_height"):
        low, high = last.args["reach_height"]
        expected = dataclasses.replace(expected, height_m=(low, high))
    assert ReachVolume.from_json(metadata.reach_volume) == expected, recipe.name
    # Every entry but a load, which a policy trained from a load has (its recipe's last stage says which).
    load = last.args.get("load")
    assert set(metadata.entries) == (set(CONTRACT_KEYS) - ({START_LOAD} if load is None else set())) | set(TRAINER_KEYS)
    assert metadata.entries.get(START_LOAD) == load
    assert metadata.contract() == {key: value for key, value in read_entries(policy).items() if key in CONTRACT_KEYS}


def test_a_missing_required_entry_is_named_and_an_optional_one_is_none():
    full = read_entries(SHIPPED[0])
    for key in REQUIRED_KEYS:
        with pytest.raises(MissingMetadataError, match=key) as raised:
            PolicyMetadata.from_entries({k: v for k, v in full.items() if k != key}, "p.onnx")
        assert raised.value.key == key
    bare = PolicyMetadata.from_entries({key: full[key] for key in REQUIRED_KEYS}, "p.onnx")
    assert (bare.spec_version, bare.action_spec, bare.noise_scale, bare.reward, bare.style, bare.trainer_version,
            bare.training_summary) == (None,) * 7


@pytest.mark.parametrize("key, value", [
    ("punch_frames", "-5"), ("punch_frames", "5.0"), ("punch_frames", "\u0663"), ("punch_physics_hz", ""),
    ("punch_smoothing_window", "99999999999"), ("punch_reach_volume", "[1, 2]"), ("punch_reach_volume", "{"),
    ("punch_training_summary", "[1, 2]"), ("punch_training_summary", '{"a": NaN}'), ("punch_spec_version", "three"),
])
def test_an_entry_that_does_not_read_as_its_type_is_named(key: str, value: str):
    entries = {**read_entries(SHIPPED[0]), key: value}
    with pytest.raises(PolicyFileError, match=key) as raised:
        PolicyMetadata.from_entries(entries, "p.onnx")
    assert raised.value.key == key


def test_what_the_writer_writes_reads_back_and_a_contract_short_of_a_key_is_refused(tmp_path: Path):
    contract = read_policy_metadata(SHIPPED[0]).contract()
    contract.pop("punch_noise_scale")
    model = ActorCritic(int(contract["punch_observation_size"]), int(contract["punch_action_size"]))
    model.set_normalization(np.random.default_rng(0).normal(size=(50, model.obs_mean.shape[0])))
    path = export_policy(model, tmp_path / "policy.onnx", contract=contract, reward="straight", summary={"run": 1})
    metadata = read_policy_metadata(path)
    assert metadata.contract() == contract and metadata.reward == "straight" and metadata.style == "none"
    assert metadata.training_summary == {"run": 1} and metadata.noise_scale is None
    assert list(read_entries(path)) == [*contract, *TRAINER_KEYS], "the contract first, in its order"
    with pytest.raises(MissingMetadataError, match="punch_smoothing_window"):
        export_policy(model, tmp_path / "short.onnx", contract={k: v for k, v in contract.items() if k != "punch_smoothing_window"},
                      reward="straight", summary={})
    assert not (tmp_path / "short.onnx").exists()


def test_a_file_that_is_no_policy_is_a_policy_file_error(tmp_path: Path):
    with pytest.raises(PolicyFileError, match="not found"):
        read_policy_metadata(tmp_path / "absent.onnx")
    (tmp_path / "garbage.onnx").write_bytes(b"not a model")
    with pytest.raises(PolicyFileError, match="not an ONNX model"):
        read_policy_metadata(tmp_path / "garbage.onnx")
    onnx.save(onnx.helper.make_model(onnx.helper.make_graph([], "empty", [], [])), str(tmp_path / "bare.onnx"))
    with pytest.raises(MissingMetadataError, match="punch_reach_volume"):
        read_policy_metadata(tmp_path / "bare.onnx")
