"""Readers of recorded pushing data sets, into this package's scenes and recordings (planar_lcp.spec.recordings).

`mit`: the MIT pushing data set (Yu et al., IROS 2016), its h5 files and object outlines (docs/real_pushes.md);
`outline`: the planar geometry it needs (convex pieces of a non-convex outline, signed distance, registration);
`cli`: the commands `planar-lcp pushdata predict` and `fit`; `score`: their scores of predicted against recorded
pushes; `model_file`: the model file (MODEL.json) fit writes and predict reads.
Adapters at the edge: nothing in the simulator imports them.
"""
