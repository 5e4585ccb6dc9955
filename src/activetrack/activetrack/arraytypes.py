"""Array type aliases of the core's signatures (numpy.typing; no numpy mypy plugin needed).

``FloatArray`` is what the core returns (float64 arrays, batched over leading axes ``...``;
typed as any floating dtype, which is what numpy's stubs give for float64 arithmetic);
``BoolArray`` the detection masks; ``ArrayLike`` what it accepts (lists, scalars, arrays).
"""

from __future__ import annotations

from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

__all__ = ["ArrayLike", "BoolArray", "FloatArray"]

ArrayLike: TypeAlias = npt.ArrayLike
FloatArray: TypeAlias = npt.NDArray[np.floating[Any]]
BoolArray: TypeAlias = npt.NDArray[np.bool_]
