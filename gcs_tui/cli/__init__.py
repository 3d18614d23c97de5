"""The headless face: the ``gcs`` command (:mod:`gcs_tui.cli.commands`), the planning
commands (:mod:`gcs_tui.cli.trade`), the progress lines on stderr
(:mod:`gcs_tui.cli.progress`), the plain-text tables (:mod:`gcs_tui.cli.tables`) and the
exported residual plots (:mod:`gcs_tui.cli.export`). ``python -m gcs_tui.cli`` runs the
command. Nothing here imports Textual.
"""
