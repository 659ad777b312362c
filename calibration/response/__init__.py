"""The camera's response curve from an exposure bracket: reading it, the methods, the record."""
