"""Planning across targets (moving into :mod:`activetrack.planning`)."""
