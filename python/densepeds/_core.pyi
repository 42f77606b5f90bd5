"""Type stubs for the Rust extension `densepeds._core` (hand-checked against the bindings)."""

import numpy as np
import numpy.typing as npt

__version__: str

# --- crowd (frvo) -------------------------------------------------------------------------------

# --- tracker (assoc) ----------------------------------------------------------------------------
