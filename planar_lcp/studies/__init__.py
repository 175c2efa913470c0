"""Commands and studies on top of the core: Stewart & Trinkle's two examples (`study_cli`: `planar-lcp study`;
`falling_rod`, `four_disks`, `common`, `accuracy`), ours against pymunk (`compare`, `compare_plots`, `compare_cli`)
and real pushes (`pushdata`). The core never imports them."""
