"""Built-in structure files (TOML), loaded by name through rcwa.load_structure."""
