"""Experiments built on the core, apart from it: benchmarks (bench.py), the pymunk bridge and comparison
(pymunk_bridge.py, compare.py), the speed/accuracy trade-off (tradeoff.py), Stewart & Trinkle's studies (studies/) and the
readers of third-party data: the LCP corpus (lcp_corpus.py) and recorded pushes (pushdata/). The core
(planar_lcp.sim, .model, .engine) never imports them."""
