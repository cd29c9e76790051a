"""Render layer, ground truth: the Monte-Carlo reference (``reference``, ``ws.reference``; kernel side
``reference_wp``, sampling ``@wp.func``s ``sampling``) and the per-region error against it
(``region_error``)."""
