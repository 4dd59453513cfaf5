"""A run's state between rounds as ``checkpoints/latest.pt`` keeps it: the learner, the replay,
the random generators, the counters and the curriculum; and its restoration on resume, refused
where the checkpoint was made with other settings."""

from __future__ import annotations

import torch

from dualarm.errors import InputError
from dualarm.training.config import TrainConfig
from dualarm.training.run_dir import CheckpointError


def trainer_state(trainer) -> dict:
    """What ``Trainer.save`` writes (call between rounds only)."""
    return {
        "config": trainer.stored_config().with_(episodes=1).to_dict(),
        "learner": trainer.agent.state_dict(),
        "replay": trainer.buffer.state_dict(),
        "rng": trainer.rng.bit_generator.state,
        "torch_rng": torch.get_rng_state(),
        "counters": {"episodes": trainer.episodes, "env_steps": trainer.env_steps,
                     "updates_owed": trainer.updates.owed, "wall_time_s": trainer.wall_time_s,
                     "eval_rows": trainer.eval_rows, "best": list(trainer.best),
                     "recent_success": list(trainer.recent_success),
                     "recent_return": list(trainer.recent_return),
                     "last_eval": trainer.last_eval},
        "curriculum": trainer.curriculum.state_dict() if trainer.curriculum is not None else None,
    }


def restore_trainer(trainer, payload: dict) -> None:
    """Restore a ``Trainer`` to the state ``trainer_state`` gave (its config must match but
    for ``episodes``).

    Raises:
        CheckpointError: other settings, or a payload of another version.
    """
    where = trainer.paths.latest
    mine = trainer.stored_config().with_(episodes=1).to_dict()
    theirs = payload.get("config", {})
    try:   # settings added since the checkpoint was written take their defaults
        theirs = TrainConfig.from_dict(theirs, base=TrainConfig.paper()).to_dict()
    except (InputError, TypeError):
        pass
    changed = sorted(k for k in mine if mine.get(k) != theirs.get(k))
    if changed:
        raise CheckpointError(f"{where}: the checkpoint was made with different settings "
                              f"({', '.join(changed)}) than {trainer.paths.config}")
    try:
        trainer.agent.load_state_dict(payload["learner"])
        trainer.buffer.load_state_dict(payload["replay"])
        trainer.rng.bit_generator.state = payload["rng"]
        torch.set_rng_state(payload["torch_rng"])
        k = payload["counters"]
        trainer.episodes, trainer.env_steps = int(k["episodes"]), int(k["env_steps"])
        trainer.updates.owed, trainer.wall_time_s = float(k["updates_owed"]), float(k["wall_time_s"])
        trainer.eval_rows, trainer.best = int(k["eval_rows"]), tuple(k["best"])
        trainer.recent_success.extend(k["recent_success"])
        trainer.recent_return.extend(k["recent_return"])
        trainer.last_eval = k["last_eval"]
        if trainer.curriculum is not None:
            trainer.curriculum.load_state_dict(payload["curriculum"])
    except (KeyError, ValueError, RuntimeError, TypeError) as exc:
        raise CheckpointError(f"{where}: incompatible with this run or this version "
                              f"({type(exc).__name__}: {exc})") from None
