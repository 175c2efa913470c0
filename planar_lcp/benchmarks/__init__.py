"""Benchmarks and sweeps: `bench` (`planar-lcp bench`: per step against pymunk, Lemke against QuantEcon, scaling,
piles against Box2D v3, compile time), `tradeoff` (the speed/accuracy sweep) and `lcp_corpus` (the third-party LCP
instances the demo, bench lcp and the tests solve). The core never imports them."""
