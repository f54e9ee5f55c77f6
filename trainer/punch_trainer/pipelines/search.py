"""`punch search`: trajectory search for a reward, its dataset, and its run directory."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from punch_trainer.learn.checkpoint import CHECKPOINT_FILE, CONFIG_FILE, CheckpointError, load_checkpoint, stored_config, write_config
from punch_trainer.learn.dataset import record_dataset
from punch_trainer.learn.search import SearchArgs, SearchResult, trajectory_search
from punch_trainer.report.motion import motion_report
from punch_trainer.report.search_report import write_search_run
from punch_trainer.reward.rewards import load_reward, reward_fingerprint
from punch_trainer.reward.style import style_named
from punch_trainer.sim.backend import LOCAL, Backend
from punch_trainer.sim.rollouts import RolloutPool


def run_search(args: SearchArgs, progress: bool = True, resume: bool = False, *,
               backend: Backend = LOCAL) -> tuple[Path, SearchResult, dict[str, Any]]:
    """The whole `punch search` command: search, dataset, run directory, with the training servers on
    `backend`. `resume` continues the run in `args.out` from its checkpoint (the CLI reads its arguments back
    with `checkpoint.read_config`)."""
    reward = load_reward(args.reward, args.frames, style_named(args.style, args.style_weight))
    if reward.frames % args.decision_period:
        raise ValueError(f"frames ({reward.frames}) must be a multiple of the decision period ({args.decision_period})")
    out = args.run_dir()
    if not resume and (out / CHECKPOINT_FILE).exists():
        raise CheckpointError(f"{out} already holds a search; continue it with `punch search --resume {out}` or choose another --out")
    fingerprint = reward_fingerprint(reward)
    if resume and (out / CONFIG_FILE).exists():
        recorded = stored_config(out).get("reward_fingerprint")
        if recorded != fingerprint and not (recorded is None and fingerprint.startswith("preset:")):
            raise CheckpointError(f"the reward {reward.name} is not the code {out} was started with (its source's "
                                  f"fingerprint is {fingerprint}, the run's {recorded}); a resume continues with the same reward")
    if resume:
        load_checkpoint(out, "search")  # its checksum and owner, before a simulator starts (its values: restore_search)
    write_config(out, args, frames=reward.frames, reward_fingerprint=fingerprint)  # first, so that an interrupted run can be resumed
    with RolloutPool(args.processes, args.characters_per_process, decision_period=args.decision_period, backend=backend) as pool:
        result = trajectory_search(args, reward, pool, progress, run_dir=out)
        info = pool.info
    dataset = record_dataset(result, reward, args, backend=backend)
    report = motion_report(dataset)
    write_search_run(out, args, reward, result, dataset, report, info)
    return out, result, report
