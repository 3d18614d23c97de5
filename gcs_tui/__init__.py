"""GCS terminal UI: the analyst's face of :mod:`gcs_core` (replaces the seed's GESS terminal).

Public API
----------
- :func:`gcs_tui.app.run_tui` — run the TUI on a mission directory or analysis config.
- :class:`gcs_tui.app.GcsApp` — the Textual app (``GcsApp(source, workbench=, save_path=,
  start_view=)``).
- :class:`gcs_tui.workbench.Workbench` — the session the screens show, without Textual.
- :mod:`gcs_tui.format` — numbers with units and honest precision.

The TUI never touches storage: files are read and written through :mod:`gcs_core`.
"""
