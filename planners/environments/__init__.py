"""The Gymnasium environments and what runs them (docs/gym.md, docs/closed_loop.md).

`push_t`: `planar_lcp/PushT-v0`, gym-pusht's Push-T on our physics; `task_env`: `planar_lcp/Task-v0`, any task file
as an environment; `inputs`: their input checks; `raster`: their numpy rasterizer; `gym_pusht_process`: gym-pusht's own
environment driven in its own virtualenv through `gym_pusht_server.py`; `pusht_eval`: episodes of a policy and
their scores (`planar-lcp pusht-eval`). `import planners` registers the two ids by name and imports none of these.
"""
