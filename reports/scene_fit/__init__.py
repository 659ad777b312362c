"""The inverse problem: the scene parameters the photos constrain, and the verdict."""
