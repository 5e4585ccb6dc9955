"""The simulated world: targets, platforms and their sensors' scans (:mod:`.simulator`)."""
