//! Static pivot orders: Markowitz's choice, the fill-in, the guard's arithmetic and the
//! coverage of a full R-S-S-R revolution.

use super::*;
use crate::validate::load_file;

fn load(path: &str) -> (Mechanism, Symbolic) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mech = load_file(&root.join(path)).unwrap().mechanism;
    // The system before its closed forms are substituted: the 20 unknowns of the R-S-S-R.
    let sys = Symbolic::build_full(&mech).unwrap();
    (mech, sys)
}

fn pattern_of(a: &[Vec<f64>]) -> Vec<Vec<bool>> {
    a.iter().map(|r| r.iter().map(|&x| x != 0.0).collect()).collect()
}

#[test]
fn markowitz_takes_singletons_first_and_avoids_fill_in() {
    // An arrow matrix with its dense row and column first: pivoting on (0, 0) first would fill
    // everything, while the singleton-like diagonal entries create none.
    let a = vec![
        vec![4.0, 1.0, 1.0, 1.0],
        vec![1.0, 3.0, 0.0, 0.0],
        vec![1.0, 0.0, 3.0, 0.0],
        vec![1.0, 0.0, 0.0, 3.0],
    ];
    let order = choose(&pattern_of(&a), &a).unwrap();
    // After the two cost-0 steps, (0, 0) and (3, 3) both cost 1 and are the largest in their
    // columns; the lower column wins the tie.
    assert_eq!(order.rows, [1, 2, 0, 3]);
    assert_eq!(order.cols, [1, 2, 0, 3]);
    // No fill-in: L and U hold exactly the 10 non-zeros.
    assert_eq!(order.entries(), 10);
    assert_eq!(largest_multiplier(&order, &a), Some(1.0 / 3.0));
}

#[test]
fn threshold_refuses_small_pivots_even_when_they_are_sparser() {
    // Column 0 has a tiny entry in a row with one non-zero (cost 0) and a large one in a full
    // row; the tiny one is below CHOICE_THRESHOLD of its column and must not be chosen.
    let a = vec![vec![1e-3, 0.0], vec![1.0, 1.0]];
    let order = choose(&pattern_of(&a), &a).unwrap();
    assert_eq!(
        (order.rows.as_slice(), order.cols.as_slice()),
        ([1, 0].as_slice(), [1, 0].as_slice())
    );
    assert_eq!(largest_multiplier(&order, &a), Some(0.0));
}

#[test]
fn fill_in_is_structural_and_markowitz_avoids_it() {
    // Eliminating with (0, 0) first fills (1, 2) and (2, 1); the pattern of that order holds
    // all 9 entries. Markowitz starts from a cheaper pivot instead and creates no fill-in.
    let a = vec![vec![3.0, 1.0, 1.0], vec![1.0, 1.0, 0.0], vec![1.0, 0.0, 1.0]];
    let natural = Order {
        rows: vec![0, 1, 2],
        cols: vec![0, 1, 2],
        pattern: vec![vec![0, 1, 2], vec![0, 1, 2], vec![0, 1, 2]],
    };
    // Step 1 divides the filled (2, 1) = −1/3 by the pivot 2/3, both rounded.
    let m = largest_multiplier(&natural, &a).unwrap();
    assert!((m - 0.5).abs() <= 1e-15, "{m}");
    assert_eq!(largest_multiplier(&natural, &vec![vec![0.0; 3]; 3]), None);
    let chosen = choose(&pattern_of(&a), &a).unwrap();
    assert_eq!(chosen.entries(), 7);
    assert_ne!(chosen.rows[0], 0);
    let singular = vec![vec![1.0, 1.0], vec![1.0, 1.0]];
    assert_eq!(choose(&pattern_of(&singular), &singular), None);
}

#[test]
fn two_orders_cover_a_full_rssr_revolution() {
    let (mech, sys) = load("benches/rssr_revolution.toml");
    let mut samples = Vec::new();
    motion(&mech, &sys, |t, q| {
        samples.push((t, q.to_vec()));
        true
    });
    assert_eq!(samples.len(), 1001);
    let s = structure(&sys);
    assert_eq!((s.len(), s.iter().flatten().filter(|&&b| b).count()), (20, 78));
    let orders = plan(&sys, &samples);
    assert_eq!(orders.len(), 2);
    assert!(orders.iter().all(|o| o.entries() == 92), "14 fill-ins each");
    let mut first = [0; 2];
    for (t, q) in &samples {
        let a = numeric(&sys, q, *t);
        let m: Vec<Option<f64>> = orders.iter().map(|o| largest_multiplier(o, &a)).collect();
        let k = m
            .iter()
            .position(|m| m.is_some_and(|m| m <= RUNTIME_MAX_MULTIPLIER))
            .unwrap_or_else(|| panic!("t = {t}: no order passes: {m:?}"));
        first[k] += 1;
    }
    // Order 0, chosen at the start, serves most of the turn; order 1 the part around half a
    // turn where one of order 0's pivots passes through zero.
    assert_eq!(first, [876, 125]);
}

#[test]
fn planning_samples_a_bounded_evenly_spaced_subset_of_the_grid() {
    use crate::model::TimeGrid;
    for count in [1, 2, MAX_SAMPLES, MAX_SAMPLES + 1, 10_007, 10_000_000] {
        let grid = TimeGrid::uniform(0.0, 1.0, count);
        let kept: Vec<usize> = (0..count).filter(|&k| grid.sampled(k, MAX_SAMPLES)).collect();
        assert_eq!(kept.len(), count.min(MAX_SAMPLES), "{count} points");
        assert_eq!((kept[0], kept[kept.len() - 1]), (0, count - 1), "{count} points");
        // Evenly spaced: consecutive gaps differ by at most one grid step (rounding).
        let gaps: Vec<usize> = kept.windows(2).map(|w| w[1] - w[0]).collect();
        if let (Some(lo), Some(hi)) = (gaps.iter().min(), gaps.iter().max()) {
            assert!(hi - lo <= 1, "{count} points: gaps from {lo} to {hi}");
        }
    }
}

#[test]
fn the_motion_visits_at_most_max_samples_configurations() {
    let (mut mech, sys) = load("benches/rssr_revolution.toml");
    // Ten times the benchmark's points over the same revolution: every one is solved (the
    // branch is followed at the grid's spacing), MAX_SAMPLES of them are visited.
    mech.time.count = 10 * (mech.time.count - 1) + 1;
    mech.time.step /= 10.0;
    let mut visited = Vec::new();
    motion(&mech, &sys, |t, _| {
        visited.push(t);
        true
    });
    assert_eq!(visited.len(), MAX_SAMPLES);
    let last = mech.time.at(mech.time.count - 1);
    assert_eq!((visited[0], visited[MAX_SAMPLES - 1]), (mech.time.start, last));
    // The same two orders as from every point of the benchmark's grid.
    let orders = plan_motion(&mech, &sys);
    assert_eq!(orders.len(), 2);
}

#[test]
fn an_input_rotation_is_planned_over_a_turn_as_its_law_would_be() {
    // `benches/rssr_input.toml` is the revolution benchmark with its crank's rotation about y
    // an input: planning sweeps the input through one turn over the `[time]` grid, which is the
    // benchmark's law 146.6 t, so it finds the law's two orders. Without the inputs in the
    // planning walk, the driver's Jacobian entries were NaN and no order was planned at all.
    let (law_mech, law_sys) = load("benches/rssr_revolution.toml");
    let (mech, sys) = load("benches/rssr_input.toml");
    assert_eq!(sys.inputs.len(), 1);
    let (law, input) = (plan_motion(&law_mech, &law_sys), plan_motion(&mech, &sys));
    assert_eq!(input.len(), 2);
    assert_eq!(input, law);
    // A joint rotation as an input (the four-bar's crank) is planned too.
    let (mech, sys) = load("examples/inputs/four_bar_input.toml");
    assert!(!plan_motion(&mech, &sys).is_empty());
}
