//! Which f32 GEMM to use at the trainer's skinny shapes: `matrixmultiply` (its own
//! threads), the `gemm` crate with its rayon threading, and the `gemm` crate
//! single-threaded per fixed block of rows (or of the reduction, for `x^T g`) spread
//! over rayon by maaf. Shapes are the three products of a dense layer with N rows,
//! `in` inputs and 64 outputs: forward `x W` (N x in x 64), input gradient `g W^T`
//! (N x 64 x in, B transposed) and weight gradient `x^T g` (in x N x 64, A transposed).
//! Throughput "elem/s" is FLOP/s.
//!
//! Run: `cargo bench -p maaf-autodiff --bench gemm_compare`
#![allow(unsafe_code)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use maaf_autodiff::check::tests_support::random_tensor;
use rayon::prelude::*;

/// `C [m, n] (row-major, contiguous) = A [m, k] B [k, n]`, with A and B given by
/// slices and (row, column) strides.
#[derive(Clone, Copy)]
struct Product<'a> {
    m: usize,
    k: usize,
    n: usize,
    a: &'a [f32],
    a_strides: (usize, usize),
    b: &'a [f32],
    b_strides: (usize, usize),
}

/// Rows of C (or reduction steps) per block in the blocked variants.
const BLOCK: usize = 2048;

impl Product<'_> {
    fn flops(&self) -> u64 {
        (2 * self.m * self.k * self.n) as u64
    }

    fn check(&self, c: &[f32]) {
        let last = |(rs, cs): (usize, usize), r: usize, col: usize| (r - 1) * rs + (col - 1) * cs;
        assert!(last(self.a_strides, self.m, self.k) < self.a.len());
        assert!(last(self.b_strides, self.k, self.n) < self.b.len());
        assert!(c.len() >= self.m * self.n);
    }

    fn matrixmultiply(&self, c: &mut [f32]) {
        self.check(c);
        let ((rsa, csa), (rsb, csb)) = (self.a_strides, self.b_strides);
        // SAFETY: `check` bounds every index of A, B and C; C is a unique borrow.
        unsafe {
            matrixmultiply::sgemm(
                self.m,
                self.k,
                self.n,
                1.0,
                self.a.as_ptr(),
                rsa as isize,
                csa as isize,
                self.b.as_ptr(),
                rsb as isize,
                csb as isize,
                0.0,
                c.as_mut_ptr(),
                self.n as isize,
                1,
            )
        }
    }

    fn gemm(&self, c: &mut [f32], parallelism: gemm::Parallelism) {
        self.check(c);
        let ((rsa, csa), (rsb, csb)) = (self.a_strides, self.b_strides);
        // SAFETY: `check` bounds every index of A, B and C; C is a unique borrow.
        // `read_dst = false`, so C's old values are ignored (dst = 1 * A B).
        unsafe {
            gemm::gemm(
                self.m,
                self.n,
                self.k,
                c.as_mut_ptr(),
                1,
                self.n as isize,
                false,
                self.a.as_ptr(),
                csa as isize,
                rsa as isize,
                self.b.as_ptr(),
                csb as isize,
                rsb as isize,
                0.0,
                1.0,
                false,
                false,
                false,
                parallelism,
            )
        }
    }

    /// Blocks of `BLOCK` rows of C on rayon, each a single-threaded `gemm` call; when
    /// C has fewer rows than a block, blocks of the reduction with partial products
    /// summed in block order instead.
    fn blocked(&self, c: &mut [f32]) {
        let ((rsa, csa), (rsb, _)) = (self.a_strides, self.b_strides);
        if self.m >= BLOCK {
            c[..self.m * self.n]
                .par_chunks_mut(BLOCK * self.n)
                .enumerate()
                .for_each(|(i, cb)| {
                    let rows = cb.len() / self.n;
                    let sub = Product {
                        m: rows,
                        a: &self.a[i * BLOCK * rsa..],
                        ..*self
                    };
                    sub.gemm(cb, gemm::Parallelism::None);
                });
            return;
        }
        let blocks = self.k.div_ceil(BLOCK);
        let partials: Vec<Vec<f32>> = (0..blocks)
            .into_par_iter()
            .map(|j| {
                let depth = BLOCK.min(self.k - j * BLOCK);
                let sub = Product {
                    k: depth,
                    a: &self.a[j * BLOCK * csa..],
                    b: &self.b[j * BLOCK * rsb..],
                    ..*self
                };
                let mut part = vec![0.0; self.m * self.n];
                sub.gemm(&mut part, gemm::Parallelism::None);
                part
            })
            .collect();
        c[..self.m * self.n].fill(0.0);
        for part in &partials {
            for (d, s) in c.iter_mut().zip(part) {
                *d += s;
            }
        }
    }
}

fn compare(c: &mut Criterion) {
    let mut group = c.benchmark_group("gemm_compare");
    group.sample_size(10);
    let out = 64;
    for rows in [10_000, 60_000] {
        for inputs in [41, 64] {
            let x: Vec<f32> = random_tensor::<f32>(&[rows, inputs], -1.0, 1.0, 1).into_vec();
            let g: Vec<f32> = random_tensor::<f32>(&[rows, out], -1.0, 1.0, 2).into_vec();
            let w: Vec<f32> = random_tensor::<f32>(&[inputs, out], -1.0, 1.0, 3).into_vec();
            let products = [
                (
                    "x W",
                    Product {
                        m: rows,
                        k: inputs,
                        n: out,
                        a: &x,
                        a_strides: (inputs, 1),
                        b: &w,
                        b_strides: (out, 1),
                    },
                ),
                (
                    "g W^T",
                    Product {
                        m: rows,
                        k: out,
                        n: inputs,
                        a: &g,
                        a_strides: (out, 1),
                        b: &w,
                        b_strides: (1, out),
                    },
                ),
                (
                    "x^T g",
                    Product {
                        m: inputs,
                        k: rows,
                        n: out,
                        a: &x,
                        a_strides: (1, inputs),
                        b: &g,
                        b_strides: (out, 1),
                    },
                ),
            ];
            for (what, p) in products {
                let mut c = vec![0f32; p.m * p.n];
                group.throughput(Throughput::Elements(p.flops()));
                let name = |lib: &str| format!("{what} N={rows} in={inputs} {lib}");
                group.bench_function(name("matrixmultiply"), |b| {
                    b.iter(|| p.matrixmultiply(&mut c))
                });
                group.bench_function(name("gemm-rayon"), |b| {
                    b.iter(|| p.gemm(&mut c, gemm::Parallelism::Rayon(0)))
                });
                group.bench_function(name("gemm-blocked"), |b| b.iter(|| p.blocked(&mut c)));
            }
        }
    }
    for n in [512, 2048] {
        let a: Vec<f32> = random_tensor::<f32>(&[n, n], -1.0, 1.0, 1).into_vec();
        let b: Vec<f32> = random_tensor::<f32>(&[n, n], -1.0, 1.0, 2).into_vec();
        let p = Product {
            m: n,
            k: n,
            n,
            a: &a,
            a_strides: (n, 1),
            b: &b,
            b_strides: (n, 1),
        };
        let mut c = vec![0f32; n * n];
        group.throughput(Throughput::Elements(p.flops()));
        let name = |lib: &str| format!("square {n} {lib}");
        group.bench_function(name("matrixmultiply"), |bch| {
            bch.iter(|| p.matrixmultiply(&mut c))
        });
        group.bench_function(name("gemm-rayon"), |bch| {
            bch.iter(|| p.gemm(&mut c, gemm::Parallelism::Rayon(0)))
        });
    }
    group.finish();
}

criterion_group!(benches, compare);
criterion_main!(benches);
