"""The simulator's random streams: common random numbers across policies.

``common`` (the default): every source of randomness of the world draws from its own stream,
keyed from the run's seed sequence, so that what one policy does cannot shift another
source's draws:

- target i's motion (its start at birth, then one motion draw per epoch): stream
  ``(TARGET, i)``, read in order; targets move the same under every policy (they do not react
  to the sensors);
- sensor j at epoch k: stream ``(DETECTION, j, k)`` for the detection draw and the measurement
  noise of every alive target (scenario order, one detection draw and one noise draw each,
  detected or not), and ``(CLUTTER, j, k)`` for its false alarms and the shuffle of the scan.
  A sensor that does not look at epoch k leaves every other stream where it was; a sensor that
  looks at the same place gets the same detections, noise and clutter.

``sequential``: everything from the one generator in the order of
:mod:`activetrack.simulation.simulator` (how the Ramdaras reproduction's tables were drawn).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

__all__ = ["RANDOM_STREAMS", "RandomStreams", "StreamsMode"]

StreamsMode = Literal["common", "sequential"]
RANDOM_STREAMS: tuple[StreamsMode, ...] = ("common", "sequential")

# First entry of a stream's key: which source of randomness it feeds.
TARGET, DETECTION, CLUTTER = 0, 1, 2


class RandomStreams:
    """The generators of one run's world, from ``rng`` (a generator made from a seed sequence,
    as :func:`activetrack.closed_loop.components.component_rngs` gives): in ``common`` mode
    only its seed sequence is used, as the root of the keyed streams."""

    def __init__(self, rng: np.random.Generator, mode: StreamsMode = "common"):
        if mode not in RANDOM_STREAMS:
            raise ValueError(f"random_streams must be one of {list(RANDOM_STREAMS)}, got {mode!r}")
        self.mode = mode
        self.rng = rng
        self._targets: dict[int, np.random.Generator] = {}
        if mode == "common":
            root = getattr(rng.bit_generator, "seed_seq", None)
            if not isinstance(root, np.random.SeedSequence):
                raise ValueError(
                    "random_streams common: the simulator's generator must be made from a seed "
                    "sequence (np.random.default_rng(seed))"
                )
            self._root = root

    @property
    def common(self) -> bool:
        return self.mode == "common"

    def _keyed(self, *key: int) -> np.random.Generator:
        ss = np.random.SeedSequence(self._root.entropy, spawn_key=(*self._root.spawn_key, *key))
        return np.random.Generator(np.random.PCG64(ss))

    def target(self, i: int) -> np.random.Generator:
        """Target i's motion stream (the one generator in ``sequential`` mode)."""
        if not self.common:
            return self.rng
        if i not in self._targets:
            self._targets[i] = self._keyed(TARGET, i)
        return self._targets[i]

    def detection(self, j: int, k: int) -> np.random.Generator:
        """Sensor j's detection draws and noise at epoch k."""
        return self._keyed(DETECTION, j, k) if self.common else self.rng

    def clutter(self, j: int, k: int) -> np.random.Generator:
        """Sensor j's false alarms and scan shuffle at epoch k."""
        return self._keyed(CLUTTER, j, k) if self.common else self.rng
