"""Experiments built on the core, apart from it: benchmarks (bench.py), the pymunk bridge and comparison
(pymunk_bridge.py, compare.py), the speed/accuracy trade-off (tradeoff.py), the seed's studies (studies/) and the
third-party LCP corpus reader (lcp_corpus.py). The core (planar_lcp.sim, .model, .engine) never imports them."""
