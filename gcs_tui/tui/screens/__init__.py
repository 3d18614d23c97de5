"""The ten GCS screens (one per module, each with a sibling ``.tcss``) and the dialogs."""
