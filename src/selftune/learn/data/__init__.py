"""The logs: :class:`Trajectory` (sample times, states, held inputs, the reference, the
rotor angle) and its files (CSV, NPZ), read with bounded memory and one-line errors."""
