"""Tracking: one filter per track on the epoch's scans, known or JPDA association, track
management (:mod:`.tracker`, :mod:`.management`)."""
