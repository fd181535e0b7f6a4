"""Sub-commands of the ``digiteyes`` CLI, one module each."""
