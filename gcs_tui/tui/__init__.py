"""The analyst's terminal UI (Textual): the app (:mod:`gcs_tui.tui.app`), its screens and
widgets, and the plain-Python side the screens read (:mod:`gcs_tui.tui.workbench`,
:mod:`gcs_tui.tui.derive`, :mod:`gcs_tui.tui.jobs`); numbers are shown by
:mod:`gcs_core.display`, as the ``gcs`` tables show them."""
