"""Opening a run directory for training, holding its lock: a new run (nothing is written until
the environment and the learner are built), or a resumed one (the config, the checkpoint and
the logs up to it are checked before anything is rewritten)."""

from __future__ import annotations

from pathlib import Path

from dualarm.atomic import atomic_copy, leftover_temporaries
from dualarm.errors import InputError
from dualarm.locks import DirectoryLock
from dualarm.training.config import TrainConfig
from dualarm.training.run_dir import RunPaths, load_checkpoint


def start_run(trainer_class, config: TrainConfig, out: str | Path, make_env=None,
              progress: bool = True):
    """``Trainer.start``: a new ``trainer_class`` run in ``out``."""
    paths = RunPaths(out)
    lock = DirectoryLock(paths.root, "dualarm train")
    try:
        if paths.config.exists() or paths.latest.exists():
            raise InputError(f"{paths.root} already holds a run: resume it with "
                             f"`dualarm train --resume {paths.root}` or choose another --out")
        trainer = trainer_class(config, paths, make_env, progress)
        source = config.constraints_file() if make_env is None else None
        if source is not None:
            atomic_copy(source, paths.constraints)
            trainer.config = trainer.config.with_(constraints=str(paths.constraints))
        trainer.stored_config().save(paths.config)
        trainer.metrics.truncate(0)
        trainer.eval_log.truncate(0)
    except BaseException:
        lock.release(remove_if_created=True)
        raise
    trainer._lock = lock
    return trainer


def resume_run(trainer_class, out: str | Path, episodes: int | None = None, make_env=None,
               progress: bool = True):
    """``Trainer.resume``: the run in ``out`` continued by a ``trainer_class``."""
    paths = RunPaths(out)
    if not paths.config.exists():
        raise InputError(f"{paths.root}: no run to resume (no config.yaml there)")
    lock = DirectoryLock(paths.root, "dualarm train")
    try:
        config = TrainConfig.load_saved(paths.config)
        if episodes is not None:
            config = config.with_(episodes=episodes)
        trainer = trainer_class(config, paths, make_env, progress)
        if paths.latest.exists():
            trainer.load(load_checkpoint(paths.latest))
        if episodes is not None and episodes < trainer.episodes:
            raise InputError(f"{paths.root}: the run has done {trainer.episodes} episodes, "
                             f"more than --episodes {episodes}; nothing was changed")
        metrics = trainer.metrics.verified(trainer.episodes)
        evaluations = trainer.eval_log.verified(trainer.eval_rows)
        if episodes is not None:
            trainer.stored_config().save(paths.config)
        trainer.metrics.rewrite(metrics)
        trainer.eval_log.rewrite(evaluations)
        for litter in leftover_temporaries(paths.checkpoints):   # a write killed mid-way
            litter.unlink()
    except BaseException:
        lock.release()
        raise
    trainer._lock = lock
    return trainer
