"""Procedurally generated object categories with ground-truth grasp frames."""
