//! Exact-as-practical geometric predicates in grid space (f64): triangle/box overlap by the
//! separating-axis test, closest point on a triangle, and 2D edge functions with a tie rule.

use glam::{DVec2, DVec3};

/// A triangle in grid space with the values every voxel test reuses.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GridTriangle {
    pub(crate) v: [DVec3; 3],
    /// Unnormalised face normal `(v1 - v0) × (v2 - v0)`.
    pub(crate) normal: DVec3,
}

impl GridTriangle {
    pub(crate) fn new(v: [DVec3; 3]) -> Self {
        Self {
            v,
            normal: (v[1] - v[0]).cross(v[2] - v[0]),
        }
    }

    /// Zero area (or non-finite): contributes no surface.
    pub(crate) fn is_degenerate(&self) -> bool {
        let n2 = self.normal.length_squared();
        n2 == 0.0 || !n2.is_finite()
    }

    pub(crate) fn min(&self) -> DVec3 {
        self.v[0].min(self.v[1]).min(self.v[2])
    }

    pub(crate) fn max(&self) -> DVec3 {
        self.v[0].max(self.v[1]).max(self.v[2])
    }

    /// Akenine-Möller triangle/box overlap for the *closed* cube `[lo, lo + 1]³`: the 9 edge ×
    /// axis cross products and the triangle plane. The three box-face axes are not tested: the
    /// caller only visits voxels inside the triangle's bounding box, which makes them pass.
    /// Touching counts as overlap, so a triangle lying on a voxel face marks that voxel.
    pub(crate) fn overlaps_unit_box(&self, lo: DVec3) -> bool {
        const HALF: f64 = 0.5;
        let c = lo + DVec3::splat(HALF);
        let v0 = self.v[0] - c;
        let v1 = self.v[1] - c;
        let v2 = self.v[2] - c;
        // Plane: |n · v0| <= r, with r the box's projected radius on n.
        let n = self.normal;
        let r = HALF * (n.x.abs() + n.y.abs() + n.z.abs());
        if n.dot(v0).abs() > r {
            return false;
        }
        let edges = [v1 - v0, v2 - v1, v0 - v2];
        for e in edges {
            // axis = unit_x × e, unit_y × e, unit_z × e.
            for axis in [
                DVec3::new(0.0, -e.z, e.y),
                DVec3::new(e.z, 0.0, -e.x),
                DVec3::new(-e.y, e.x, 0.0),
            ] {
                let p0 = axis.dot(v0);
                let p1 = axis.dot(v1);
                let p2 = axis.dot(v2);
                let r = HALF * (axis.x.abs() + axis.y.abs() + axis.z.abs());
                if p0.min(p1).min(p2) > r || p0.max(p1).max(p2) < -r {
                    return false;
                }
            }
        }
        true
    }

    /// Closest point on the triangle to `p` (Ericson, *Real-Time Collision Detection* §5.1.5)
    /// as barycentric weights `(w0, w1, w2)`, summing to 1.
    pub(crate) fn closest_barycentric(&self, p: DVec3) -> DVec3 {
        let [a, b, c] = self.v;
        let ab = b - a;
        let ac = c - a;
        let ap = p - a;
        let d1 = ab.dot(ap);
        let d2 = ac.dot(ap);
        if d1 <= 0.0 && d2 <= 0.0 {
            return DVec3::X;
        }
        let bp = p - b;
        let d3 = ab.dot(bp);
        let d4 = ac.dot(bp);
        if d3 >= 0.0 && d4 <= d3 {
            return DVec3::Y;
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let v = d1 / (d1 - d3);
            return DVec3::new(1.0 - v, v, 0.0);
        }
        let cp = p - c;
        let d5 = ab.dot(cp);
        let d6 = ac.dot(cp);
        if d6 >= 0.0 && d5 <= d6 {
            return DVec3::Z;
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let w = d2 / (d2 - d6);
            return DVec3::new(1.0 - w, 0.0, w);
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return DVec3::new(0.0, 1.0 - w, w);
        }
        let denom = va + vb + vc;
        if denom == 0.0 || !denom.is_finite() {
            // Only reachable for degenerate triangles, which callers skip; stay finite anyway.
            return DVec3::X;
        }
        let v = vb / denom;
        let w = vc / denom;
        DVec3::new(1.0 - v - w, v, w)
    }

    /// The point with barycentric weights `bary`.
    pub(crate) fn point(&self, bary: DVec3) -> DVec3 {
        self.v[0] * bary.x + self.v[1] * bary.y + self.v[2] * bary.z
    }
}

/// Twice the signed area of `(a, b, p)`; positive when `p` is left of `a → b`.
fn orient(a: DVec2, b: DVec2, p: DVec2) -> f64 {
    (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
}

/// `orient(a, b, p)` evaluated with the endpoints in a canonical (lexicographic) order and the
/// sign fixed afterwards, so `edge(a, b, p) == -edge(b, a, p)` bit for bit: the two triangles
/// sharing an edge see exactly opposite values, and a tie is a tie for both.
pub(crate) fn edge(a: DVec2, b: DVec2, p: DVec2) -> f64 {
    if (a.x, a.y) <= (b.x, b.y) {
        orient(a, b, p)
    } else {
        -orient(b, a, p)
    }
}

/// Top-left rule for a counter-clockwise triangle: an edge owns the points exactly on it when
/// it runs downward, or horizontally toward −x. Of two triangles on opposite sides of a shared
/// edge exactly one owns it, and of a fan around a vertex exactly one owns the vertex.
pub(crate) fn owns_edge(a: DVec2, b: DVec2) -> bool {
    b.y < a.y || (b.y == a.y && b.x < a.x)
}

/// Whether the counter-clockwise 2D triangle `t` contains `p` under the top-left rule, and if
/// so the barycentric weights of `p`.
pub(crate) fn point_in_ccw_triangle(t: [DVec2; 3], p: DVec2) -> Option<DVec3> {
    let mut w = [0.0; 3];
    for i in 0..3 {
        let a = t[(i + 1) % 3];
        let b = t[(i + 2) % 3];
        let e = edge(a, b, p);
        if e < 0.0 || (e == 0.0 && !owns_edge(a, b)) {
            return None;
        }
        w[i] = e;
    }
    let sum = w[0] + w[1] + w[2];
    if sum <= 0.0 || !sum.is_finite() {
        return None;
    }
    Some(DVec3::new(w[0], w[1], w[2]) / sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_edge_point_belongs_to_exactly_one_triangle() {
        // Two CCW triangles sharing the diagonal (0,0)-(1,1) of a unit square; probe points on
        // the diagonal, on the square's corners and on its outer edges.
        let a = DVec2::new(0.0, 0.0);
        let b = DVec2::new(1.0, 0.0);
        let c = DVec2::new(1.0, 1.0);
        let d = DVec2::new(0.0, 1.0);
        let t1 = [a, b, c];
        let t2 = [a, c, d];
        for k in 0..=8 {
            let f = f64::from(k) / 8.0;
            let p = DVec2::new(f, f);
            let n = usize::from(point_in_ccw_triangle(t1, p).is_some())
                + usize::from(point_in_ccw_triangle(t2, p).is_some());
            let inside_square = f > 0.0 && f < 1.0;
            if inside_square {
                assert_eq!(n, 1, "diagonal point {p:?} claimed {n} times");
            } else {
                assert!(n <= 1, "corner {p:?} claimed {n} times");
            }
        }
    }

    #[test]
    fn vertex_of_a_fan_is_owned_once() {
        // Six triangles around the origin, all CCW.
        let centre = DVec2::ZERO;
        let ring: Vec<DVec2> = (0..6)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::TAU / 6.0 + 0.1;
                DVec2::new(a.cos(), a.sin())
            })
            .collect();
        let owners = (0..6)
            .filter(|&i| {
                point_in_ccw_triangle([centre, ring[i], ring[(i + 1) % 6]], centre).is_some()
            })
            .count();
        assert_eq!(owners, 1);
    }

    #[test]
    fn box_overlap_touching_and_separated() {
        let t = GridTriangle::new([
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 0.0, 1.0),
        ]);
        // Lies on the shared face x = 1 of voxels 0 and 1: touching counts for both.
        assert!(t.overlaps_unit_box(DVec3::ZERO));
        assert!(t.overlaps_unit_box(DVec3::X));
        assert!(!t.overlaps_unit_box(DVec3::new(2.0, 0.0, 0.0)));
        // A sloped triangle whose bounding box covers a voxel it misses.
        let s = GridTriangle::new([
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(0.0, 3.0, 3.0),
        ]);
        assert!(!s.overlaps_unit_box(DVec3::new(2.0, 2.0, 0.0)));
        assert!(s.overlaps_unit_box(DVec3::new(1.0, 1.0, 1.0)));
    }

    #[test]
    fn closest_point_regions() {
        let t = GridTriangle::new([DVec3::ZERO, DVec3::X, DVec3::Y]);
        let inside = t.closest_barycentric(DVec3::new(0.25, 0.25, 5.0));
        assert!((t.point(inside) - DVec3::new(0.25, 0.25, 0.0)).length() < 1e-12);
        assert_eq!(t.closest_barycentric(DVec3::new(-1.0, -1.0, 0.0)), DVec3::X);
        let on_edge = t.point(t.closest_barycentric(DVec3::new(1.0, 1.0, 0.0)));
        assert!((on_edge - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-12);
    }
}
