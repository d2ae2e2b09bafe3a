"""Tasks as data and the scenes drawn from them.

Task specs and their TOML files, the two scenes a task is drawn in, seeded scene sampling,
whether a task may be mirrored, and a drawn scene's picture.
"""
