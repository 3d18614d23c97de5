"""The faces of :mod:`gcs_core` (replacing the seed's GESS terminal): the headless ``gcs``
command (:mod:`gcs_tui.cli`) and the analyst's terminal UI (:mod:`gcs_tui.tui`). Both open
a config through :func:`gcs_core.config.config_for` and show numbers by the one rule of
:mod:`gcs_core.display`.

Public API
----------
- :func:`gcs_tui.cli.commands.main` — the ``gcs`` command (``python -m gcs_tui.cli``).
- :func:`gcs_tui.tui.app.run_tui` — run the TUI on a mission directory or analysis config.
- :class:`gcs_tui.tui.app.GcsApp` — the Textual app (``GcsApp(source, workbench=, save_path=,
  start_view=)``).
- :class:`gcs_tui.tui.workbench.Workbench` — the session the screens show, without Textual.
- :mod:`gcs_core.display` — numbers with units and honest precision, for both faces.

The TUI never touches storage: files are read and written through :mod:`gcs_core`.
"""
