"""Reusable widgets of the GCS TUI (chrome, plots)."""
