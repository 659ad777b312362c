"""Built-in scene files (TOML), loaded by name through renderer.scene.load_scene."""
