//! The "paper" configuration reproduces Ad, Bd, Kx and Ky of docs/model.md section 6.3.
#![allow(clippy::needless_range_loop)]

use dca_core::design::{MpcDesign, MpcParams};
use dca_core::params::PlantParams;

const TOL: f64 = 1e-6;

fn assert_rel(name: &str, got: f64, want: f64) {
    let err = ((got - want) / want).abs();
    assert!(
        err <= TOL,
        "{name}: got {got:e}, want {want:e}, rel err {err:e}"
    );
}

fn design(np: usize, nc: usize) -> MpcDesign {
    MpcDesign::new(
        &PlantParams::NOMINAL,
        MpcParams {
            np,
            nc,
            ts_s: 0.1,
            rw: 33.0,
        },
    )
    .expect("paper design")
}

#[test]
fn ad_bd_at_ts_0_1() {
    let d = design(6, 2);
    // docs/model.md prints Ad and Bd to 7 significant digits: compare to that precision.
    #[rustfmt::skip]
    let ad = [
        [0.7341909, 5.455700e-3, 2.822454e-5],
        [-1.821804, 0.1876496, 5.204337e-3],
        [-335.9234, -102.5988, 0.1413006],
    ];
    let bd = [1.268632, 160.2266, -25442.86];
    for i in 0..3 {
        for j in 0..3 {
            let err = ((d.ad[(i, j)] - ad[i][j]) / ad[i][j]).abs();
            assert!(
                err < 1e-6,
                "Ad[{i}][{j}] = {:e}, want {:e}",
                d.ad[(i, j)],
                ad[i][j]
            );
        }
        let err = ((d.bd[i] - bd[i]) / bd[i]).abs();
        assert!(err < 1e-6, "Bd[{i}] = {:e}, want {:e}", d.bd[i], bd[i]);
    }
}

#[test]
fn mpc_gains_np6_nc2() {
    let d = design(6, 2);
    assert_rel("Kx0", d.kx[0], 0.2471624659);
    assert_rel("Kx1", d.kx[1], 9.182641853e-4);
    assert_rel("Kx2", d.kx[2], 1.491136307e-5);
    assert_rel("Ky", d.ky, 0.1604827894);
    assert_rel("Ky = Kmpc[3]", d.ky_state, d.ky);
}

#[test]
fn mpc_eso_gains_np8_nc3() {
    let d = design(8, 3);
    assert_rel("Kx0", d.kx[0], 0.2719556416);
    assert_rel("Kx1", d.kx[1], 9.683988187e-4);
    assert_rel("Kx2", d.kx[2], 1.632334523e-5);
    assert_rel("Ky", d.ky, 0.1646407320);
    assert_rel("Ky = Kmpc[3]", d.ky_state, d.ky);
}

#[test]
fn phi_is_lower_triangular_toeplitz_and_f_rows_follow_a() {
    let d = design(8, 3);
    for i in 0..8 {
        for j in 0..3 {
            if j > i {
                assert_eq!(d.phi[(i, j)], 0.0);
            } else if j > 0 {
                assert_eq!(d.phi[(i, j)], d.phi[(i - 1, j - 1)]);
            }
        }
    }
    // F row i+1 = F row i * A.
    for i in 0..7 {
        let next = d.f.fixed_view::<1, 4>(i, 0) * d.a;
        for k in 0..4 {
            let want = d.f[(i + 1, k)];
            assert!((next[k] - want).abs() <= 1e-12 * want.abs().max(1.0));
        }
    }
    // Nothing outside the np x nc block.
    assert!(d.phi.rows(8, 24).iter().all(|&v| v == 0.0));
    assert!(d.f.rows(8, 24).iter().all(|&v| v == 0.0));
}
