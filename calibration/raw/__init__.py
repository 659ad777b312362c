"""Raw photographs decoded to linear camera RGB, and damaged or unsupported raws refused."""
