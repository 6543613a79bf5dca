"""Drake LeafSystems, one per pipeline stage, each beside the plain-Python core it wraps."""
