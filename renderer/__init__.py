"""Rendering with Mitsuba 3: the BWDF plugin, scenes, camera model (issues 4-5).

Only renderer.variant exists so far: it finds a usable libLLVM and sets Mitsuba's
variant, once per process.
"""
