"""Demonstration sets: file formats and labels, generation, loading, segmentation."""
