"""Pose and field of view of a scene photograph: edges, the edge fit, the render check, uncertainty."""
