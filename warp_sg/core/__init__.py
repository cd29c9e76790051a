"""Base layer: what every layer needs and nothing numeric — the typed input errors, device
selection, atomic file writes, the worker-count policy, mesh validation, the size watchdog, image
files and the on-disk cache. Imports nothing of the project outside this folder."""
