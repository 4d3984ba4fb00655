"""Criteria of retargeted motion: functional (tracking) now, human-likeness with issue 4."""
