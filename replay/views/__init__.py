"""The Rerun views: the only package that imports rerun (entry point: `replay.views.recording`)."""
