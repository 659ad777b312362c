"""Intrinsics from board views: lens models, the choice among them, uncertainty, vignetting."""
