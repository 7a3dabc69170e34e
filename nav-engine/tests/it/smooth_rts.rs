//! The closed-loop RTS backward pass (`nav_engine::smooth`) against the textbook open-loop
//! Rauch-Tung-Striebel smoother on a linear-Gaussian system, where the two must agree to
//! rounding: a 9-state system with a dense random Phi, driven by noise, measured at some steps
//! (3 components), filtered twice: open loop (state estimate propagated, textbook RTS) and
//! closed loop (the estimate fed back into a nominal after each update, the error state reset
//! to zero, the history stored as the filter's recorder stores it). Also: a break in the chain
//! (a segment boundary) and the refusal of a history with unrecorded predictions.
use nalgebra::{DMatrix, DVector};
use nav_engine::smooth::{smooth, History, Node, SmoothError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

const N: usize = 9;

fn pack(p: &DMatrix<f64>) -> Vec<f64> {
    let mut v = Vec::new();
    for i in 0..N {
        for j in i..N {
            v.push(p[(i, j)]);
        }
    }
    v
}

fn phi_rows(phi: &DMatrix<f64>) -> Vec<f64> {
    // the 9 core rows (n = 9: no diagonal part)
    (0..N)
        .flat_map(|i| (0..N).map(move |j| (i, j)))
        .map(|(i, j)| phi[(i, j)])
        .collect()
}

struct Case {
    phis: Vec<DMatrix<f64>>,
    q: DMatrix<f64>,
    h: DMatrix<f64>,
    r: DMatrix<f64>,
    /// measurement at step k (None: no update)
    z: Vec<Option<DVector<f64>>>,
    p0: DMatrix<f64>,
    x0_hat: DVector<f64>,
}

fn case(seed: u64, steps: usize) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = || -> f64 { rng.sample(StandardNormal) };
    let q = DMatrix::from_diagonal(&DVector::from_fn(N, |i, _| 1e-3 * (1.0 + i as f64)));
    let h = DMatrix::from_fn(3, N, |i, j| if j == 6 + i { 1.0 } else { 0.0 });
    let r = DMatrix::from_diagonal(&DVector::from_element(3, 0.04));
    let p0 = DMatrix::from_diagonal(&DVector::from_fn(N, |i, _| 0.5 + 0.1 * i as f64));
    let mut x = DVector::from_fn(N, |i, _| p0[(i, i)].sqrt() * g());
    let x0_hat = DVector::zeros(N);
    let mut phis = Vec::new();
    let mut z = vec![None];
    for k in 0..steps {
        // a slowly varying, dense, mildly unstable transition
        let phi = DMatrix::identity(N, N) + DMatrix::from_fn(N, N, |_, _| 0.05 * g());
        x = &phi * &x + DVector::from_fn(N, |i, _| q[(i, i)].sqrt() * g());
        phis.push(phi);
        // measured at 2 of 3 steps, none in an "outage" from 40 to 60
        let meas = k % 3 != 2 && !(40..60).contains(&k);
        z.push(meas.then(|| &h * &x + DVector::from_fn(3, |_, _| 0.2 * g())));
    }
    Case {
        phis,
        q,
        h,
        r,
        z,
        p0,
        x0_hat,
    }
}

/// Open-loop KF + textbook RTS: smoothed states.
fn textbook(c: &Case) -> Vec<DVector<f64>> {
    let mut xf = Vec::new();
    let mut pf = Vec::new();
    let mut xp = vec![c.x0_hat.clone()];
    let mut pp = vec![c.p0.clone()];
    let mut x = c.x0_hat.clone();
    let mut p = c.p0.clone();
    for k in 0..c.z.len() {
        if let Some(z) = &c.z[k] {
            let s = &c.h * &p * c.h.transpose() + &c.r;
            let kg = &p * c.h.transpose() * s.try_inverse().unwrap();
            x = &x + &kg * (z - &c.h * &x);
            p = (DMatrix::identity(N, N) - &kg * &c.h) * &p;
        }
        xf.push(x.clone());
        pf.push(p.clone());
        if let Some(phi) = c.phis.get(k) {
            x = phi * &x;
            p = phi * &p * phi.transpose() + &c.q;
            xp.push(x.clone());
            pp.push(p.clone());
        }
    }
    let m = xf.len();
    let mut xs = vec![DVector::zeros(N); m];
    xs[m - 1] = xf[m - 1].clone();
    for k in (0..m - 1).rev() {
        let a = &pf[k] * c.phis[k].transpose() * pp[k + 1].clone().try_inverse().unwrap();
        xs[k] = &xf[k] + a * (&xs[k + 1] - &xp[k + 1]);
    }
    xs
}

/// Closed-loop filter recording the history the way `smooth::Recorder` does; returns the
/// stored (post-feedback) nominal per node and the history.
fn closed_loop(c: &Case) -> (Vec<DVector<f64>>, Vec<Node>) {
    let mut nominal = c.x0_hat.clone();
    let mut p = c.p0.clone();
    let mut nodes: Vec<Node> = Vec::new();
    let mut stored = Vec::new();
    let mut prior = c.p0.clone();
    for k in 0..c.z.len() {
        let mut correction = None;
        if let Some(z) = &c.z[k] {
            // z = predicted - measured, dx = K z (estimate minus truth), nominal -= dx
            let innov = &c.h * &nominal - z;
            let s = &c.h * &p * c.h.transpose() + &c.r;
            let kg = &p * c.h.transpose() * s.try_inverse().unwrap();
            let dx = &kg * innov;
            nominal -= &dx;
            p = (DMatrix::identity(N, N) - &kg * &c.h) * &p;
            correction = Some(dx.iter().copied().collect());
        }
        stored.push(nominal.clone());
        let post = (p != prior).then(|| pack(&p));
        nodes.push(Node {
            t_s: k as f64 * 0.1,
            p_prior: pack(&prior),
            p_post: post,
            correction,
            phi: c.phis.get(k).map(phi_rows),
        });
        if let Some(phi) = c.phis.get(k) {
            nominal = phi * &nominal;
            p = phi * &p * phi.transpose() + &c.q;
            prior = p.clone();
        }
    }
    (stored, nodes)
}

/// The history of `nodes` (in its temporary file).
fn history(nodes: &[Node]) -> History {
    History::from_nodes(N, nodes.iter().cloned()).unwrap()
}

#[test]
fn closed_loop_rts_equals_the_textbook_smoother_on_a_linear_system() {
    for seed in 1..=3 {
        let c = case(seed, 100);
        let xs = textbook(&c);
        let (nominal, nodes) = closed_loop(&c);
        let hist = history(&nodes);
        assert_eq!(hist.read_nodes().unwrap(), nodes);
        let sm = smooth(&hist).unwrap();
        assert_eq!(sm.pinv_fallbacks, 0);
        let sm = sm.load().unwrap();
        assert_eq!(sm.t_s.len(), xs.len());
        let mut worst = 0.0f64;
        let mut moved = 0.0f64;
        for k in 0..xs.len() {
            let dx = DVector::from_column_slice(&sm.dx_post[k * N..(k + 1) * N]);
            let x_closed = &nominal[k] - dx;
            worst = worst.max((&x_closed - &xs[k]).amax());
            moved = moved.max((&nominal[k] - &xs[k]).amax());
        }
        println!("seed {seed}: largest difference {worst:.3e}, smoothing moved the state by up to {moved:.3}");
        // the smoother changes the forward estimate by O(1) (the outage) and agrees with
        // the textbook to rounding
        assert!(moved > 0.1, "{moved}");
        assert!(worst < 1e-9 * moved.max(1.0), "{worst}");
    }
}

#[test]
fn smoothed_covariance_is_below_the_filtered_one_and_equals_it_at_the_end() {
    let c = case(7, 100);
    let (_, nodes) = closed_loop(&c);
    let sm = smooth(&history(&nodes)).unwrap().load().unwrap();
    let m = nodes.len();
    for (k, node) in nodes.iter().enumerate() {
        let post = node.post();
        // diagonal of the packed posterior: index of (i, i)
        let mut idx = 0;
        for i in 0..N {
            let pf = post[idx];
            let ps = sm.var[k * N + i];
            assert!(
                ps <= pf * (1.0 + 1e-9) && ps > 0.0,
                "node {k} state {i}: {ps} vs {pf}"
            );
            if k == m - 1 {
                assert!((ps - pf).abs() <= 1e-12 * pf);
            }
            idx += N - i;
        }
    }
}

#[test]
fn a_broken_chain_restarts_from_the_filtered_solution() {
    let c = case(3, 60);
    let (_, mut nodes) = closed_loop(&c);
    // break between node 29 and 30: node 29 is the end of a segment
    nodes[29].phi = None;
    let mut hist = history(&nodes);
    let sm = smooth(&hist).unwrap().load().unwrap();
    assert!(!sm.linked[29] && sm.linked[28]);
    // node 29 keeps the filtered solution (zero error), node 28 is smoothed
    assert!(sm.dx_post[29 * N..30 * N].iter().all(|v| *v == 0.0));
    assert!(sm.dx_post[28 * N..29 * N].iter().any(|v| v.abs() > 1e-6));
    hist.unobserved_predictions = 2;
    assert_eq!(smooth(&hist).err(), Some(SmoothError::Unobserved(2)));
    assert_eq!(smooth(&History::default()).err(), Some(SmoothError::Empty));
}
