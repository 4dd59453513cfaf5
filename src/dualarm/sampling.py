"""Uniform draws in discs and balls, for start states and hindsight goals (one place, so that
every caller samples a region the same way)."""

from __future__ import annotations

import numpy as np


def ball_offsets(rng: np.random.Generator, shape: tuple, radius: float) -> np.ndarray:
    """Points drawn uniformly from the ball of ``radius`` about 0 in the last axis of
    ``shape`` (..., G): a uniform direction times radius x u^(1/G)."""
    direction = rng.normal(size=shape)
    direction /= np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-12)
    scale = radius * rng.random(shape[:-1] + (1,)) ** (1.0 / shape[-1])
    return direction * scale


def disc_offset(rng: np.random.Generator, radius: float) -> np.ndarray:
    """A point (2,) drawn uniformly from the disc of ``radius`` about 0, by radius and angle
    (the draws ``approach_spread``'s runs were made with)."""
    r, angle = radius * np.sqrt(rng.uniform()), 2 * np.pi * rng.uniform()
    return np.array([r * np.cos(angle), r * np.sin(angle)])
