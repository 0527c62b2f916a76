//! Times the two matrix-product libraries of the host kernels, `matrixmultiply` and the `gemm`
//! crate, on the shapes of an MLP layer's passes, to check the rule that picks between them
//! (`GEMM_CRATE_MIN_K` in `host_net.rs`: the `gemm` crate from an inner dimension of 5 on).
//!
//! ```text
//! cargo run --release -p apo-core --example matmul_shapes            # parts of 1 250 rows
//! cargo run --release -p apo-core --example matmul_shapes -- 500 50  # rows per part, repeats
//! ```
//!
//! For each layer `[input → output]` and both libraries it prints the milliseconds and GFLOP/s
//! of 8 parts' forward product `X·W` (`[rows, input]·[input, output]`), weight gradient `Xᵀ·D`
//! and input gradient `D·Wᵀ`, one thread, as the update's batch of 10 000 rows runs them.

use std::time::Instant;

type Product =
    fn((usize, usize, usize), &[f32], (isize, isize), &[f32], (isize, isize), &mut [f32]);

/// `C = A·B`, `A` `[m, k]` and `B` `[k, n]` with (row, column) strides, `C` row-major.
fn with_matrixmultiply(
    (m, k, n): (usize, usize, usize),
    a: &[f32],
    (rsa, csa): (isize, isize),
    b: &[f32],
    (rsb, csb): (isize, isize),
    c: &mut [f32],
) {
    assert!(a.len() >= m * k && b.len() >= k * n && c.len() >= m * n);
    // SAFETY: every operand holds its `[rows, cols]` elements under the strides given.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            1.0,
            a.as_ptr(),
            rsa,
            csa,
            b.as_ptr(),
            rsb,
            csb,
            0.0,
            c.as_mut_ptr(),
            n as isize,
            1,
        )
    }
}

/// The same product with the `gemm` crate (`dst = alpha·dst + beta·lhs·rhs`, column stride
/// first).
fn with_gemm_crate(
    (m, k, n): (usize, usize, usize),
    a: &[f32],
    (rsa, csa): (isize, isize),
    b: &[f32],
    (rsb, csb): (isize, isize),
    c: &mut [f32],
) {
    assert!(a.len() >= m * k && b.len() >= k * n && c.len() >= m * n);
    // SAFETY: as above; `c` is not read (`read_dst` false).
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            1,
            n as isize,
            false,
            a.as_ptr(),
            csa,
            rsa,
            b.as_ptr(),
            csb,
            rsb,
            0.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
}

fn main() {
    let mut args = std::env::args().skip(1).map(|a| a.parse::<usize>());
    let (rows, repeats) = match (args.next(), args.next()) {
        (None, _) => (1250, 200),
        (Some(Ok(r)), None) if r > 0 => (r, 200),
        (Some(Ok(r)), Some(Ok(n))) if r > 0 && n > 0 => (r, n),
        _ => {
            eprintln!("usage: matmul_shapes [ROWS_PER_PART ≥ 1 [REPEATS ≥ 1]]");
            std::process::exit(2);
        }
    };
    let parts = 8;
    let fill = |len: usize, mul: usize| -> Vec<f32> {
        (0..len)
            .map(|i| ((i * mul) % 1000) as f32 / 1000.0 - 0.5)
            .collect()
    };
    println!("{parts} parts of {rows} rows, {repeats} repeats, one thread");
    for (input, output) in [(60, 64), (64, 64), (64, 8), (64, 2), (64, 1)] {
        let x = fill(rows * input, 7919);
        let w = fill(input * output, 104_729);
        let d = fill(rows * output, 31);
        let (mut c, mut g, mut dx) = (
            vec![0.0; rows * output],
            vec![0.0; input * output],
            vec![0.0; rows * input],
        );
        let flop = 2.0 * (rows * parts * input * output) as f64;
        for (name, product) in [
            ("matrixmultiply", with_matrixmultiply as Product),
            ("gemm", with_gemm_crate as Product),
        ] {
            let time = |run: &mut dyn FnMut()| {
                let start = Instant::now();
                for _ in 0..repeats * parts {
                    run();
                }
                start.elapsed().as_secs_f64() / repeats as f64
            };
            let (i, o) = (input as isize, output as isize);
            let forward =
                time(&mut || product((rows, input, output), &x, (i, 1), &w, (o, 1), &mut c));
            let weight =
                time(&mut || product((input, rows, output), &x, (1, i), &d, (o, 1), &mut g));
            let grad_in =
                time(&mut || product((rows, output, input), &d, (o, 1), &w, (1, o), &mut dx));
            let show = |s: f64| format!("{:.3} ms ({:.0} GFLOP/s)", s * 1e3, flop / s / 1e9);
            println!(
                "[{input} → {output}] {name:>14}: forward {}, weight gradient {}, input gradient {}",
                show(forward),
                show(weight),
                show(grad_in)
            );
        }
    }
}
