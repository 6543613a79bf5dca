"""Diagram builders, scenarios and scene/object construction for the dual-arm stack."""
