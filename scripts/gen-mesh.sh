#!/bin/sh
# gen-mesh.sh: write test meshes as Wavefront OBJ to stdout (the import tests and
# scripts/gen-import-md.sh use them; data/meshes/water.obj was made by it).
#
#   scripts/gen-mesh.sh sphere NU NV R CX CY CZ
#       a UV sphere of radius R centred at (CX, CY, CZ): NU segments around y, NV bands from pole
#       to pole, vertices on the sphere, one vn per vertex (the exact normal), quads as 4-gons
#       (the reader splits them), the pole caps as triangles, counter-clockwise from outside.
#   scripts/gen-mesh.sh water N X0 X1 Z0 Z1 Y0 Y1 A
#       a closed slab of "water": the top is the height field y = Y1 + A sin(2 pi u) sin(3 pi v)
#       (u, v in [0, 1] across the slab), sampled on an N x N grid, the bottom the plane y = Y0,
#       and four vertical sides; every face's front is outside. Negative indices are used for
#       the sides, so the reader's relative indexing is exercised too.
set -eu
kind=${1:-}
case "$kind" in
sphere)
    [ $# -eq 7 ] || { echo "usage: $0 sphere NU NV R CX CY CZ" >&2; exit 2; }
    awk -v nu="$2" -v nv="$3" -v r="$4" -v cx="$5" -v cy="$6" -v cz="$7" 'BEGIN {
        pi = atan2(0, -1)
        print "# UV sphere, " nu " x " nv
        print "v " cx " " cy + r " " cz; print "vn 0 1 0"
        for (j = 1; j < nv; j++) {
            th = pi * j / nv
            for (i = 0; i < nu; i++) {
                ph = 2 * pi * i / nu
                x = sin(th) * cos(ph); y = cos(th); z = -sin(th) * sin(ph)
                printf "v %.17g %.17g %.17g\nvn %.17g %.17g %.17g\n", cx + r * x, cy + r * y, cz + r * z, x, y, z
            }
        }
        print "v " cx " " cy - r " " cz; print "vn 0 -1 0"
        # vertex k of ring j (1-based rings), i around: 2 + (j - 1) nu + i
        for (i = 0; i < nu; i++) {
            a = 2 + i; b = 2 + (i + 1) % nu
            printf "f 1//1 %d//%d %d//%d\n", a, a, b, b
        }
        for (j = 1; j < nv - 1; j++)
            for (i = 0; i < nu; i++) {
                a = 2 + (j - 1) * nu + i; b = 2 + (j - 1) * nu + (i + 1) % nu
                c = b + nu; d = a + nu
                printf "f %d//%d %d//%d %d//%d %d//%d\n", a, a, d, d, c, c, b, b
            }
        s = 2 + (nv - 1) * nu
        for (i = 0; i < nu; i++) {
            a = 2 + (nv - 2) * nu + i; b = 2 + (nv - 2) * nu + (i + 1) % nu
            printf "f %d//%d %d//%d %d//%d\n", s, s, b, b, a, a
        }
    }'
    ;;
water)
    [ $# -eq 9 ] || { echo "usage: $0 water N X0 X1 Z0 Z1 Y0 Y1 A" >&2; exit 2; }
    awk -v n="$2" -v x0="$3" -v x1="$4" -v z0="$5" -v z1="$6" -v y0="$7" -v y1="$8" -v amp="$9" 'BEGIN {
        pi = atan2(0, -1)
        print "# water slab, " n " x " n " height field"
        # top grid: vertex (i, k) = 1 + k (n + 1) + i
        for (k = 0; k <= n; k++)
            for (i = 0; i <= n; i++) {
                u = i / n; v = k / n
                printf "v %.17g %.17g %.17g\n", x0 + (x1 - x0) * u, y1 + amp * sin(2 * pi * u) * sin(3 * pi * v), z0 + (z1 - z0) * v
            }
        for (k = 0; k < n; k++)
            for (i = 0; i < n; i++) {
                a = 1 + k * (n + 1) + i; b = a + 1; c = b + n + 1; d = a + n + 1
                printf "f %d %d %d %d\n", a, d, c, b
            }
        nt = (n + 1) * (n + 1)
        # the four side walls: for each edge segment of the top grid, a quad down to y0,
        # written with negative indices (its two bottom vertices are the last two defined)
        for (s = 0; s < 4; s++)
            for (t = 0; t < n; t++) {
                if (s == 0) { i0 = t; k0 = 0; i1 = t + 1; k1 = 0 }
                if (s == 1) { i0 = n; k0 = t; i1 = n; k1 = t + 1 }
                if (s == 2) { i0 = n - t; k0 = n; i1 = n - t - 1; k1 = n }
                if (s == 3) { i0 = 0; k0 = n - t; i1 = 0; k1 = n - t - 1 }
                a = 1 + k0 * (n + 1) + i0; b = 1 + k1 * (n + 1) + i1
                printf "v %.17g %.17g %.17g\n", x0 + (x1 - x0) * i0 / n, y0, z0 + (z1 - z0) * k0 / n
                printf "v %.17g %.17g %.17g\n", x0 + (x1 - x0) * i1 / n, y0, z0 + (z1 - z0) * k1 / n
                printf "f %d %d -1 -2\n", a, b
            }
        printf "v %.17g %.17g %.17g\nv %.17g %.17g %.17g\nv %.17g %.17g %.17g\nv %.17g %.17g %.17g\n", x0, y0, z0, x1, y0, z0, x1, y0, z1, x0, y0, z1
        print "f -4 -3 -2 -1"
    }'
    ;;
*)
    echo "usage: $0 sphere NU NV R CX CY CZ | water N X0 X1 Z0 Z1 Y0 Y1 A" >&2
    exit 2
    ;;
esac
