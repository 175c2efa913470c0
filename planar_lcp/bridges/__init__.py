"""A scene in another simulator, for comparison: `pymunk` (compare, replay --simulator pymunk, bench step's peer) and
`box2d` (Box2D v3, bench pile's peer). Each imports its simulator inside its functions; the core never imports them."""
