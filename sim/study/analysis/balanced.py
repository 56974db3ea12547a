"""Where the mixed model's fit starts (sim.study.analysis.mixed_model): in a balanced study, at its REML estimate in
closed form. Pure logic.

A study is balanced when every participant has each cell (condition × factor × path) the same number of times r, as
every simulated study of `power` has and a real one without missing trials. Split the trials then into the
participant-and-condition means and the deviations from them. The random effects live in the means only; the fixed
effects are the cells' means within a condition (in the deviations) and the condition's mean per sequence (in the
means: intercept, condition, period and sequence are those four); so the REML likelihood is a product of two:
  deviations  the residual variance σ² alone: σ̂² = their sum of squares about the cells' means / (n − 2N − 2(K − 1)),
              with n trials, N participants and K cells per condition;
  means       each participant's (VR, reality) pair, its covariance Z G Zᵀ + σ²/(K r) I, where G is the random
              intercept's and condition slope's covariance and Z = [[1, ½], [1, −½]]: estimated by the pairs'
              covariance S within each sequence, pooled (N − sequences degrees of freedom).
Each factor is maximised apart, and G = Z⁻¹ (S − σ̂²/(K r) I) Z⁻ᵀ is the REML estimate whenever it is positive
definite (inside the parameter space). The fit starts there and its optimiser stops at once, at the estimate it would
have reached from its default start, about ten steps later (to within their tolerance). Anywhere else (G on or beyond
the boundary, a study not balanced) the fit starts where statsmodels starts it: the start changes how fast the
optimum is found, never which optimum it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Balance", "balance", "reml_start"]

_Z_INVERSE = np.array([[0.5, 0.5], [1.0, -1.0]])  # (VR mean, reality mean) -> (intercept, condition slope)


@dataclass(frozen=True)
class Balance:
    """A balanced layout's indices, so that each fit's start costs a few sums."""

    cell: np.ndarray  # per row: its cell within its condition, 0..2K−1 (VR's and reality's apart)
    mean: np.ndarray  # per row: its participant-and-condition mean, 2·participant + (1 in VR)
    sequence: np.ndarray  # per participant (0..N−1): 0 or 1
    cells: int  # 2K
    per_mean: int  # K·r: the trials in a participant-and-condition mean
    df_within: int


def balance(participant: np.ndarray, vr: np.ndarray, vr_first: np.ndarray, cell: Sequence[str]) -> Balance | None:
    """The layout's Balance, or None when it is not balanced. `cell`: each row's factor and path as one label."""
    _, participant_index = np.unique(participant, return_inverse=True)
    participants = int(participant_index.max()) + 1
    cells, cell_index = np.unique([f"{in_vr}|{label}" for in_vr, label in zip(vr, cell)], return_inverse=True)
    counts = np.zeros((participants, len(cells)), dtype=int)
    np.add.at(counts, (participant_index, cell_index), 1)
    replicates = int(counts[0, 0])
    in_vr = np.array([label.startswith("True|") for label in cells])
    if not (np.all(counts == replicates) and 0 < in_vr.sum() == len(cells) - in_vr.sum()):
        return None
    sequence = np.zeros(participants, dtype=int)
    sequence[participant_index] = np.asarray(vr_first, dtype=bool).astype(int)
    per_mean = replicates * len(cells) // 2
    return Balance(
        cell=cell_index,
        mean=2 * participant_index + np.asarray(vr, dtype=bool).astype(int),
        sequence=sequence,
        cells=len(cells),
        per_mean=per_mean,
        df_within=len(participant) - 2 * participants - (len(cells) - 2),
    )


def reml_start(layout: Balance, values: np.ndarray) -> np.ndarray | None:
    """G / σ̂² (the random effects' covariance relative to the residual variance: what statsmodels optimises), or
    None when it is not positive definite or there is nothing to estimate σ² from."""
    participants = layout.sequence.shape[0]
    sequences = len(np.unique(layout.sequence))
    if layout.df_within < 1 or participants - sequences < 1:
        return None
    means = np.bincount(layout.mean, values, 2 * participants) / layout.per_mean
    cell_means = np.bincount(layout.cell, values, layout.cells) / (values.shape[0] / layout.cells)
    condition_means = np.bincount(layout.mean % 2, values, 2) / (values.shape[0] / 2)
    cell_condition = np.bincount(layout.cell, layout.mean % 2, layout.cells) > 0  # the cell's condition is VR
    within = values - means[layout.mean] - cell_means[layout.cell] + condition_means[cell_condition[layout.cell] * 1]
    residual = float(within @ within) / layout.df_within
    pairs = means.reshape(participants, 2)[:, ::-1]  # (VR, reality) per participant
    centred = pairs.copy()
    for sequence in np.unique(layout.sequence):
        chosen = layout.sequence == sequence
        centred[chosen] -= pairs[chosen].mean(axis=0)
    between = centred.T @ centred / (participants - sequences) - residual / layout.per_mean * np.eye(2)
    start = _Z_INVERSE @ between @ _Z_INVERSE.T / residual
    if not (residual > 0.0 and np.all(np.isfinite(start)) and np.linalg.eigvalsh(start)[0] > 0.0):
        return None
    return start
