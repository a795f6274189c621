# CoACD run for `pegtwin assembly decompose`: a JSON mesh on stdin (vertices, triangles,
# threshold, seed), the convex parts' vertices as JSON on stdout. Exit 3: coacd is missing.
import json
import sys

job = json.load(sys.stdin)  # read whole first: pegtwin writes it all before it reads
try:
    import coacd
    import numpy as np
except ImportError as e:
    print(f"{e}", file=sys.stderr)
    sys.exit(3)
coacd.set_log_level("error")
# An STL repeats each corner per triangle: weld equal corners so that CoACD sees one surface.
vertices, index = np.unique(np.array(job["vertices"], dtype=float), axis=0, return_inverse=True)
triangles = index.reshape(-1)[np.array(job["triangles"], dtype=int)]
mesh = coacd.Mesh(vertices, triangles)
parts = coacd.run_coacd(
    mesh, threshold=job["threshold"], preprocess_mode="off", seed=job["seed"]
)
json.dump({"parts": [np.asarray(v).tolist() for v, _ in parts]}, sys.stdout)
