//! The curve families and their options (DESIGN section 3), as the user chooses them.

/// A curve family.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Curve {
    /// Piecewise geodesic through the keys (glTF LINEAR). C0.
    Slerp,
    /// Shoemake's spherical quadrangle through the keys. C1 in the segment parameter.
    Squad,
    /// One KKS Bezier curve of degree n with the keys as control points.
    Bezier,
    /// Per-segment KKS cubic Hermite through the keys with end angular velocities. C1.
    Hermite,
    /// Per-segment Nam-Kim blend of two great arcs through the keys. C1.
    NamKim,
    /// KKS order-k B-spline with the keys as control points. C^(k-2), approximating.
    BSpline,
    /// A B-spline on the quaternions' components, normalized: `q = (sum B_i c_i) / |sum B_i
    /// c_i|`, with the keys as control points. The order and knots of [`Curve::BSpline`] and
    /// its continuity, approximating; no exponential, so the cheapest smooth family to
    /// evaluate. The control points of one span must lie less than a half turn apart, so the
    /// sum never vanishes.
    NormalizedBSpline,
    /// KKS cubic B-spline through every key at its time (KKS section 6.2): C2, interpolating,
    /// natural ends (or periodic when looping). The builder solves its control points, after
    /// which every evaluator sees a cubic B-spline on explicit knots.
    BSplineInterp,
}

/// How a B-spline's knot vector is made (DESIGN section 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum KnotMode {
    /// KKS appendix uniform cubic B-spline with phantom end points; passes through the end keys.
    Phantom,
    /// Plain uniform knots (robotics convention).
    Uniform,
    /// End knots repeated k times; interpolates both end keys.
    Clamped,
    /// The track's own knot vector.
    Explicit,
}

/// Where Hermite and Nam-Kim take their key angular velocities from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Tangents {
    /// Non-uniform Catmull-Rom estimate from the neighbouring keys.
    CatmullRom,
    /// Zero angular velocity at every key.
    Zero,
    /// The track's `angular_velocities` (body frame, rad/s).
    Given,
}

/// Nam-Kim's blend function `f(s)` with `f(0) = 0, f(1) = 1, f'(0) = f'(1) = 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Blend {
    /// `f = 3 s^2 - 2 s^3`.
    Cubic,
    /// NK's piecewise quadratic: `2 s^2` then `1 - 2 (s - 1)^2`.
    Quadratic,
}

/// Lowest B-spline order (degree + 1): a piecewise slerp.
pub const MIN_ORDER: usize = 2;
/// Highest B-spline order every evaluator runs. The CPU's fitted bases and the GPU's
/// tables are sized for it; the shader's `MAX_ORDER` is checked against it by a test.
pub const MAX_ORDER: usize = 8;

/// The curve used when none is named, by every front end (`eval`, `bake`, Python's
/// `evaluate`, `Curve` and `bake`) and by [`CurveSpec::default`]: C2 and through every key, on
/// any key times.
pub const DEFAULT_CURVE: Curve = Curve::BSplineInterp;

/// Everything that selects and shapes a curve, besides the track data itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CurveSpec {
    /// The family.
    pub curve: Curve,
    /// B-spline order k (degree k - 1), [`MIN_ORDER`]`..=`[`MAX_ORDER`]. Ignored by families
    /// other than the B-splines.
    pub order: usize,
    /// B-spline knot mode. Ignored by families other than the B-splines.
    pub knots: KnotMode,
    /// Tangent source for Hermite and Nam-Kim.
    pub tangents: Tangents,
    /// Blend function for Nam-Kim.
    pub blend: Blend,
    /// A periodic curve (`--loop`): the last key closes onto the first, the curve keeps its
    /// continuity class across that seam and sample times wrap by the period (DESIGN
    /// section 3, "Loops"). Which curves loop: [`CurveSpec::can_loop`].
    pub looping: bool,
}

impl Default for CurveSpec {
    /// [`CurveSpec::DEFAULT`].
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl CurveSpec {
    /// The front ends' defaults: [`DEFAULT_CURVE`]; for the families that take them, order 4,
    /// phantom knots, Catmull-Rom tangents, the cubic blend; open.
    pub const DEFAULT: Self = Self {
        curve: DEFAULT_CURVE,
        order: 4,
        knots: KnotMode::Phantom,
        tangents: Tangents::CatmullRom,
        blend: Blend::Cubic,
        looping: false,
    };

    /// A spec for `curve` with every other option at its default.
    #[must_use]
    pub fn new(curve: Curve) -> Self {
        Self { curve, ..Self::default() }
    }

    /// An open B-spline of `order` on explicit knots, the KKS cumulative form.
    #[must_use]
    pub fn open_bspline(order: usize) -> Self {
        Self::open_spline(Curve::BSpline, order)
    }

    /// An open B-spline of either form (`curve`: [`Curve::BSpline`] or
    /// [`Curve::NormalizedBSpline`]) and `order` on explicit knots: the curve of a fitted
    /// channel (`quatcurve::BatchBuilder::extend_splines`).
    #[must_use]
    pub fn open_spline(curve: Curve, order: usize) -> Self {
        Self { curve, order, knots: KnotMode::Explicit, ..Self::default() }
    }

    /// Whether this spec can loop (DESIGN section 3, "Loops"): Bezier and B-splines (either
    /// form) on uniform, clamped or explicit knots cannot.
    #[must_use]
    pub fn can_loop(&self) -> bool {
        match self.curve {
            Curve::Bezier => false,
            Curve::BSpline | Curve::NormalizedBSpline => self.knots == KnotMode::Phantom,
            _ => true,
        }
    }

    /// The curves that loop, as messages and help texts list them (from [`Self::can_loop`]):
    /// `slerp, squad, hermite, nam-kim, bspline with phantom knots, normalized-bspline with
    /// phantom knots, bspline-interp`.
    #[must_use]
    pub fn looping_curves() -> String {
        let mut names = Vec::new();
        for curve in Curve::NAMES.iter().filter_map(|n| n.parse::<Curve>().ok()) {
            let knots: Vec<KnotMode> = KnotMode::NAMES.iter().filter_map(|n| n.parse().ok()).collect();
            let looping: Vec<&str> = knots
                .iter()
                .filter(|&&k| Self { curve, knots: k, ..Self::default() }.can_loop())
                .map(|k| k.name())
                .collect();
            match (curve, looping.len()) {
                (_, 0) => {}
                (Curve::BSpline | Curve::NormalizedBSpline, _) => {
                    names.push(format!("{curve} with {} knots", looping.join(" or ")));
                }
                _ => names.push(curve.to_string()),
            }
        }
        names.join(", ")
    }

    /// Minimum key count for this spec (DESIGN section 3).
    #[must_use]
    pub fn min_keys(&self) -> usize {
        match (self.curve, self.knots) {
            (Curve::BSpline | Curve::NormalizedBSpline, KnotMode::Phantom) => 2,
            (Curve::BSpline | Curve::NormalizedBSpline, _) => self.order,
            _ => 2,
        }
    }
}

/// A type named by one of a fixed list of words: how its values are written on the command
/// line, in Python and in files ([`names!`] implements it).
pub trait Named: std::str::FromStr<Err = UnknownName> + std::fmt::Display + Clone + Send + Sync + 'static {
    /// Every accepted name, in order.
    const NAMES: &'static [&'static str];
}

/// Names as the CLI and JSON spell them: `NAMES`, `name()`, `Display`, `FromStr`, [`Named`]
/// and serde (as the name; the calling crate depends on `serde`) for an enum of unit variants
/// (quatcurve's choices: curves, devices, texture kinds, formats).
#[doc(hidden)]
#[macro_export]
macro_rules! names {
    ($ty:ty, $what:literal, $($variant:ident => $name:literal),+ $(,)?) => {
        impl $crate::curve::Named for $ty {
            const NAMES: &'static [&'static str] = &[$($name),+];
        }
        impl ::serde::Serialize for $ty {
            fn serialize<S: ::serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }
        impl<'de> ::serde::Deserialize<'de> for $ty {
            fn deserialize<D: ::serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                // A value of another type (a boolean) is refused with the names listed.
                struct Names;
                impl ::serde::de::Visitor<'_> for Names {
                    type Value = $ty;
                    fn expecting(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                        write!(f, "one of: {}", <$ty>::NAMES.join(", "))
                    }
                    fn visit_str<E: ::serde::de::Error>(self, name: &str) -> Result<$ty, E> {
                        name.parse().map_err(E::custom)
                    }
                }
                d.deserialize_str(Names)
            }
        }
        impl $ty {
            /// Every accepted name, in order.
            pub const NAMES: &'static [&'static str] = &[$($name),+];

            /// The name as the CLI spells it.
            #[must_use]
            pub fn name(self) -> &'static str {
                match self { $(Self::$variant => $name),+ }
            }
        }
        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
        impl std::str::FromStr for $ty {
            type Err = $crate::curve::UnknownName;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                match s {
                    $($name => Ok(Self::$variant),)+
                    _ => Err($crate::curve::UnknownName { what: $what, given: s.to_string(), expected: Self::NAMES }),
                }
            }
        }
    };
}
pub use names;

/// A name that is none of a type's ([`names!`]): what was named, what was given, the names
/// accepted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownName {
    /// What the name is of ("curve").
    pub what: &'static str,
    /// The name given.
    pub given: String,
    /// Every accepted name, in order.
    pub expected: &'static [&'static str],
}

impl std::fmt::Display for UnknownName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "unknown {} '{}' (expected one of: {})", self.what, self.given, self.expected.join(", "))
    }
}

impl std::error::Error for UnknownName {}

names!(Curve, "curve",
    Slerp => "slerp", Squad => "squad", Bezier => "bezier", Hermite => "hermite", NamKim => "nam-kim",
    BSpline => "bspline", NormalizedBSpline => "normalized-bspline", BSplineInterp => "bspline-interp");
names!(KnotMode, "knot mode", Phantom => "phantom", Uniform => "uniform", Clamped => "clamped", Explicit => "explicit");
names!(Tangents, "tangent source", CatmullRom => "catmull-rom", Zero => "zero", Given => "given");
names!(Blend, "blend", Cubic => "cubic", Quadratic => "quadratic");

impl Blend {
    /// Nam-Kim's blend ratio `f(s)` on `[0, 1]` (NK eq. 5 and section 2.2): the share of the
    /// second great arc at segment parameter `s`.
    #[must_use]
    pub fn ratio<R: crate::real::Real>(self, s: R) -> R {
        match self {
            Blend::Cubic => s * s * (R::cst(3.0) - s.scale(2.0)),
            Blend::Quadratic => {
                if s.value() <= 0.5 {
                    (s * s).scale(2.0)
                } else {
                    let r = s - R::cst(1.0);
                    R::cst(1.0) - (r * r).scale(2.0)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spec made without naming a curve is the one every front end uses.
    #[test]
    fn the_default_spec_is_the_front_ends_curve() {
        assert_eq!(CurveSpec::default().curve, DEFAULT_CURVE);
        assert_eq!(CurveSpec::default(), CurveSpec::new(DEFAULT_CURVE));
    }
}
