//! Pixel lanes for the blend loop: the tile kernels in the `blend` module are written
//! once over [`Lanes`], a small set of element-wise operations on `N` pixels at a
//! time. `f32` renders through `wide::f32x4` (4 pixels of a tile row per step, one
//! SSE2 instruction per operation on a default x86-64 build); `f64` (the gradient
//! checks) goes through [`One`], a single pixel, so the checked code is the fast
//! code.
//!
//! Why 4 lanes and not 8: in a trained-object scene at 200x200 most splats cover a
//! few pixels, so a wider group mostly computes masked lanes. Measured with
//! callgrind on `fwd+bwd 200x200 50k` (1 thread): scalar loop 608 M instructions
//! per frame, `f32x8` 692 M (and about 40 % slower in wall time), `f32x4` 550 M.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

use maaf_autodiff::Float;
use wide::{Select, f32x4};

/// `N` values of `T` processed together, with per-lane masks.
pub trait Lanes<T>:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Number of lanes; divides the tile width.
    const N: usize;
    /// A per-lane truth value.
    type Mask: Copy
        + BitAnd<Output = Self::Mask>
        + BitOr<Output = Self::Mask>
        + Not<Output = Self::Mask>;
    /// Every lane set to `x`.
    fn splat(x: T) -> Self;
    /// Lanes `s[0..N]`.
    fn load(s: &[T]) -> Self;
    /// Writes the lanes to `s[0..N]`.
    fn store(self, s: &mut [T]);
    /// Lane `i` holds `i` (0, 1, ..., N-1).
    fn ramp() -> Self;
    /// `e^x` per lane.
    fn exp(self) -> Self;
    /// Per-lane minimum.
    fn min(self, o: Self) -> Self;
    /// `|x|` per lane.
    fn abs(self) -> Self;
    /// `self < o` per lane.
    fn lt(self, o: Self) -> Self::Mask;
    /// `self <= o` per lane.
    fn le(self, o: Self) -> Self::Mask;
    /// `self > o` per lane.
    fn gt(self, o: Self) -> Self::Mask;
    /// `self >= o` per lane.
    fn ge(self, o: Self) -> Self::Mask;
    /// `m ? a : b` per lane.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// Bit `i` set when lane `i` of `m` is true.
    fn bits(m: Self::Mask) -> u32;
    /// Sum of the lanes in lane order (deterministic).
    fn sum(self) -> T;
}

/// A float type the rasterizer can composite: names its lane type.
pub trait SplatFloat: Float {
    /// The lanes the blend loop runs on.
    type L: Lanes<Self>;
}

impl SplatFloat for f32 {
    type L = f32x4;
}

impl SplatFloat for f64 {
    type L = One<f64>;
}

impl Lanes<f32> for f32x4 {
    const N: usize = 4;
    type Mask = f32x4;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        f32x4::splat(x)
    }
    #[inline(always)]
    fn load(s: &[f32]) -> Self {
        let a: [f32; 4] = s[..4].try_into().expect("a full lane group");
        f32x4::new(a)
    }
    #[inline(always)]
    fn store(self, s: &mut [f32]) {
        s[..4].copy_from_slice(&self.to_array());
    }
    #[inline(always)]
    fn ramp() -> Self {
        f32x4::new([0.0, 1.0, 2.0, 3.0])
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f32x4::exp(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32x4::min(self, o)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x4::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self {
        self.simd_lt(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self {
        self.simd_le(o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self {
        self.simd_gt(o)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self {
        self.simd_ge(o)
    }
    #[inline(always)]
    fn select(m: Self, a: Self, b: Self) -> Self {
        Select::select(m, a, b)
    }
    #[inline(always)]
    fn bits(m: Self) -> u32 {
        m.to_bitmask()
    }
    #[inline(always)]
    fn sum(self) -> f32 {
        self.to_array().iter().sum()
    }
}

/// One lane: a plain scalar behind the [`Lanes`] interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct One<T>(pub T);

macro_rules! one_binop {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<T: Float> $tr for One<T> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                One(self.0 $op o.0)
            }
        }
    };
}
one_binop!(Add, add, +);
one_binop!(Sub, sub, -);
one_binop!(Mul, mul, *);
one_binop!(Div, div, /);

impl<T: Float> Neg for One<T> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        One(-self.0)
    }
}

impl<T: Float> Lanes<T> for One<T> {
    const N: usize = 1;
    type Mask = bool;
    fn splat(x: T) -> Self {
        One(x)
    }
    fn load(s: &[T]) -> Self {
        One(s[0])
    }
    fn store(self, s: &mut [T]) {
        s[0] = self.0;
    }
    fn ramp() -> Self {
        One(T::zero())
    }
    fn exp(self) -> Self {
        One(self.0.exp())
    }
    fn min(self, o: Self) -> Self {
        One(self.0.min(o.0))
    }
    fn abs(self) -> Self {
        One(self.0.abs())
    }
    fn lt(self, o: Self) -> bool {
        self.0 < o.0
    }
    fn le(self, o: Self) -> bool {
        self.0 <= o.0
    }
    fn gt(self, o: Self) -> bool {
        self.0 > o.0
    }
    fn ge(self, o: Self) -> bool {
        self.0 >= o.0
    }
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m { a } else { b }
    }
    fn bits(m: bool) -> u32 {
        u32::from(m)
    }
    fn sum(self) -> T {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lane operation of `f32x4` agrees lane by lane with the one-lane version
    /// (exp to 2 ulp: `wide`'s polynomial is not libm's).
    #[test]
    fn f32x4_matches_one_lane() {
        let a: Vec<f32> = (0..4).map(|i| -3.0 + 1.8 * i as f32).collect();
        let b: Vec<f32> = (0..4).map(|i| 1.5 - 0.8 * i as f32).collect();
        let (x, y) = (
            <f32x4 as Lanes<f32>>::load(&a),
            <f32x4 as Lanes<f32>>::load(&b),
        );
        let mut out = [0.0f32; 4];
        let check = |v: f32x4, f: &dyn Fn(f32, f32) -> f32, tol: f32| {
            let got = v.to_array();
            for i in 0..4 {
                let want = f(a[i], b[i]);
                assert!(
                    (got[i] - want).abs() <= tol * want.abs(),
                    "lane {i}: {} vs {want}",
                    got[i]
                );
            }
        };
        check(x + y, &|p, q| p + q, 0.0);
        check(x - y, &|p, q| p - q, 0.0);
        check(x * y, &|p, q| p * q, 0.0);
        check(x / y, &|p, q| p / q, 0.0);
        check(-x, &|p, _| -p, 0.0);
        check(Lanes::exp(x), &|p, _| p.exp(), 2.5e-7);
        check(Lanes::min(x, y), &|p, q| p.min(q), 0.0);
        let sel = <f32x4 as Lanes<f32>>::select(Lanes::lt(x, y), x, y);
        check(sel, &|p, q| if p < q { p } else { q }, 0.0);
        let m = [
            Lanes::lt(x, y),
            Lanes::le(x, y),
            Lanes::gt(x, y),
            Lanes::ge(x, y),
        ];
        let f: [fn(f32, f32) -> bool; 4] =
            [|p, q| p < q, |p, q| p <= q, |p, q| p > q, |p, q| p >= q];
        for (mask, cmp) in m.into_iter().zip(f) {
            let want: u32 = (0..4).map(|i| u32::from(cmp(a[i], b[i])) << i).sum();
            assert_eq!(<f32x4 as Lanes<f32>>::bits(mask), want);
        }
        x.store(&mut out);
        assert_eq!(out.as_slice(), a.as_slice());
        assert_eq!(
            <f32x4 as Lanes<f32>>::ramp().to_array(),
            [0.0, 1.0, 2.0, 3.0]
        );
        assert_eq!(Lanes::sum(x), a.iter().sum::<f32>());
    }
}
