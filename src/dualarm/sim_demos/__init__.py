"""Demonstrations that need the simulator: synthetic human demonstration sets made from the
scripted expert's episodes (``generate``). Above ``envs`` in the layers, so that ``demos``
(formats, labels, loading, segmentation) stays below the constraints the environment reads."""
