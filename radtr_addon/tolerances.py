"""The engine's shared tolerances, in one place: lengths are fractions of the scene's
bounding-box diagonal unless a comment says otherwise."""

#: Embree rays leave (and shadow rays stop) this far off a surface: a surface does not shadow itself.
RAY_OFFSET = 1e-6
#: A GPU view's eye above its patch's centroid: the patch does not see itself.
EYE_LIFT = 1e-4
#: The GPU views' near plane: nearer surfaces are clipped; any nearer and 24-bit depth loses precision.
NEAR_PLANE = 1e-4
#: A parallel-ray grid spans the scene's bounding sphere widened by this factor: no edge pixel clips the scene.
BOUNDS_MARGIN = 1.01
#: Added to that sphere's radius (scene units): a scene of one point still gets pixels of nonzero size.
BOUNDS_FLOOR = 1e-9
#: A light is not traced at a point where it gives less than this fraction of the brightest light there.
CULL = 1e-3
