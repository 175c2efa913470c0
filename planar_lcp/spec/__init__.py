"""The scene description: dataclasses, TOML loading and validation (scene.py), mass properties (massprops.py), and
seeded random scenes for robustness tests (random_scenes.py). Nothing here runs a simulation."""
