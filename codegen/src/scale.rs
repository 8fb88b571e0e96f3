//! Families of mechanisms of any size, for the scaling study (`mechgen scaling`) and the
//! tests: an open chain of driven revolute links, independent spatial arms, a binary tree of
//! links and a row of independent R-S-S-R loops. All are written as description text with
//! initial estimates that satisfy every joint exactly.

use std::fmt::Write;

/// Common header: a ground body and a short time grid.
fn header(name: &str, steps: usize) -> String {
    format!(
        "name = \"{name}\"\n\n[time]\nstart = 0.0\nend = 0.02\nsteps = {steps}\n\n\
         [[bodies]]\nname = \"ground\"\nground = true\n\n"
    )
}

/// An open chain of `n` links of length 0.5 along x, each joined to the previous one (the
/// first to ground) by a revolute about global z and driven by a small harmonic rotation.
#[must_use]
pub fn chain(n: usize, steps: usize) -> String {
    let mut s = header(&format!("chain_{n}"), steps);
    for k in 1..=n {
        let x = 0.5 * (k as f64 - 1.0) + 0.25;
        let _ = write!(s, "[[bodies]]\nname = \"link{k}\"\nr = [{x:?}, 0.0, 0.0]\n\n");
    }
    for k in 1..=n {
        let (prev, point_i) = if k == 1 {
            ("ground".to_owned(), "[0.0, 0.0, 0.0]".to_owned())
        } else {
            (format!("link{}", k - 1), "[0.25, 0.0, 0.0]".to_owned())
        };
        let _ = write!(
            s,
            "[[joints]]\nname = \"hinge{k}\"\ntype = \"revolute\"\nbody_i = \"{prev}\"\n\
             body_j = \"link{k}\"\npoint_i = {point_i}\npoint_j = [-0.25, 0.0, 0.0]\n\
             axis_i = [0.0, 0.0, 1.0]\naxis_j = [0.0, 0.0, 1.0]\nref_i = [1.0, 0.0, 0.0]\n\
             ref_j = [1.0, 0.0, 0.0]\n\n\
             [[drivers]]\nname = \"motor{k}\"\njoint = \"hinge{k}\"\nmotion = \"rotation\"\n\
             law = {{ offset = 0.0, amplitude = 0.3, frequency = {:?}, phase = 0.0 }}\n\n",
            10.0 + k as f64
        );
    }
    s
}

/// `k` copies of the thesis' R-S-S-R (examples/rssr.toml), 0.3 apart along x, each with its
/// own crank driver: 3k bodies, k closed loops.
#[must_use]
pub fn rssr_loops(k: usize, steps: usize) -> String {
    let mut s = header(&format!("rssr_loops_{k}"), steps);
    for c in 0..k {
        let dx = 0.3 * c as f64;
        let _ = write!(
            s,
            "[[bodies]]\nname = \"crank{c}\"\nr = [{dx:?}, -0.06567, 0.0]\n\n\
             [[bodies]]\nname = \"coupler{c}\"\nr = [{dx:?}, 0.0, 0.1]\n\n\
             [[bodies]]\nname = \"rocker{c}\"\nr = [{:?}, 0.49977, 0.0]\n\n",
            dx - 0.0475
        );
        let _ = write!(
            s,
            "[[joints]]\nname = \"A{c}\"\ntype = \"spherical\"\nbody_i = \"crank{c}\"\n\
             body_j = \"coupler{c}\"\npoint_i = [0.0, 0.06567, 0.1]\npoint_j = [0.0, 0.0, 0.0]\n\n\
             [[joints]]\nname = \"B{c}\"\ntype = \"spherical\"\nbody_i = \"coupler{c}\"\n\
             body_j = \"rocker{c}\"\npoint_i = [0.0, 0.4812, 0.0]\npoint_j = [0.0475, -0.01857, 0.1]\n\n\
             [[joints]]\nname = \"O2_{c}\"\ntype = \"revolute\"\nbody_i = \"ground\"\n\
             body_j = \"crank{c}\"\npoint_i = [{dx:?}, -0.06567, 0.0]\npoint_j = [0.0, 0.0, 0.0]\n\
             axis_i = [0.0, 1.0, 0.0]\naxis_j = [0.0, 1.0, 0.0]\nref_i = [0.0, 0.0, 1.0]\n\
             ref_j = [0.0, 0.0, 1.0]\n\n\
             [[joints]]\nname = \"O4_{c}\"\ntype = \"revolute\"\nbody_i = \"rocker{c}\"\n\
             body_j = \"ground\"\npoint_i = [0.0, 0.0, 0.0]\npoint_j = [{:?}, 0.49977, 0.0]\n\
             axis_i = [1.0, 0.0, 0.0]\naxis_j = [1.0, 0.0, 0.0]\n\n\
             [[constraints]]\nname = \"no_spin{c}\"\ntype = \"fix\"\nbody = \"coupler{c}\"\n\
             coordinate = \"e2\"\nvalue = 0.0\n\n\
             [[drivers]]\nname = \"motor{c}\"\njoint = \"O2_{c}\"\nmotion = \"rotation\"\n\
             law = {{ start = 0.0, velocity = 146.6 }}\n\n",
            dx - 0.0475
        );
    }
    s
}

/// `count` independent arms of `links` revolute-driven links each, their bases 1.0 apart along
/// y: every link is 0.5 long along x, and its joint to the link before it (the first to
/// ground) turns about z for odd links and about y for even ones, so each arm is spatial.
#[must_use]
pub fn arms(count: usize, links: usize, steps: usize) -> String {
    let mut s = header(&format!("arms_{count}x{links}"), steps);
    for a in 1..=count {
        let y = a as f64 - 1.0;
        for k in 1..=links {
            let x = 0.5 * (k as f64 - 1.0) + 0.25;
            let _ = write!(s, "[[bodies]]\nname = \"arm{a}_link{k}\"\nr = [{x:?}, {y:?}, 0.0]\n\n");
        }
    }
    for a in 1..=count {
        let y = a as f64 - 1.0;
        for k in 1..=links {
            let (prev, point_i) = if k == 1 {
                ("ground".to_owned(), format!("[0.0, {y:?}, 0.0]"))
            } else {
                (format!("arm{a}_link{}", k - 1), "[0.25, 0.0, 0.0]".to_owned())
            };
            let axis = if k % 2 == 1 { "[0.0, 0.0, 1.0]" } else { "[0.0, 1.0, 0.0]" };
            let _ = write!(
                s,
                "[[joints]]\nname = \"arm{a}_joint{k}\"\ntype = \"revolute\"\nbody_i = \"{prev}\"\n\
                 body_j = \"arm{a}_link{k}\"\npoint_i = {point_i}\npoint_j = [-0.25, 0.0, 0.0]\n\
                 axis_i = {axis}\naxis_j = {axis}\nref_i = [1.0, 0.0, 0.0]\n\
                 ref_j = [1.0, 0.0, 0.0]\n\n\
                 [[drivers]]\nname = \"arm{a}_motor{k}\"\njoint = \"arm{a}_joint{k}\"\n\
                 motion = \"rotation\"\n\
                 law = {{ offset = 0.0, amplitude = 0.3, frequency = {:?}, phase = 0.0 }}\n\n",
                10.0 + k as f64 + 0.1 * a as f64
            );
        }
    }
    s
}

/// A binary tree of `n` revolute-driven links 0.5 long along x: link k hangs from the tip of
/// link (k − 1)/2 (link 0 from ground), turning about z at odd depths and y at even ones.
#[must_use]
pub fn tree(n: usize, steps: usize) -> String {
    let mut s = format!(
        "name = \"tree_{n}\"\n\n[time]\nstart = 0.0\nend = 0.02\nsteps = {steps}\n\n\
         [[bodies]]\nname = \"ground\"\nground = true\n\n"
    );
    let depth = |k: usize| (k + 1).ilog2() as usize;
    for k in 0..n {
        let x = 0.5 * depth(k) as f64 + 0.25;
        let _ = write!(s, "[[bodies]]\nname = \"link{k}\"\nr = [{x:?}, 0.0, 0.0]\n\n");
    }
    for k in 0..n {
        let (parent, point_i) = if k == 0 {
            ("ground".to_owned(), "[0.0, 0.0, 0.0]")
        } else {
            (format!("link{}", (k - 1) / 2), "[0.25, 0.0, 0.0]")
        };
        let axis = if depth(k) % 2 == 1 { "[0.0, 0.0, 1.0]" } else { "[0.0, 1.0, 0.0]" };
        let _ = write!(
            s,
            "[[joints]]\nname = \"joint{k}\"\ntype = \"revolute\"\nbody_i = \"{parent}\"\n\
             body_j = \"link{k}\"\npoint_i = {point_i}\npoint_j = [-0.25, 0.0, 0.0]\n\
             axis_i = {axis}\naxis_j = {axis}\nref_i = [1.0, 0.0, 0.0]\nref_j = [1.0, 0.0, 0.0]\n\n\
             [[drivers]]\nname = \"motor{k}\"\njoint = \"joint{k}\"\nmotion = \"rotation\"\n\
             law = {{ offset = 0.0, amplitude = 0.2, frequency = {:?}, phase = 0.0 }}\n\n",
            5.0 + (k % 7) as f64
        );
    }
    s
}

/// The descriptions `benches/scaling.sh` measures, by file name under `benches/scale/`:
/// chains of 10 and 100 links, one and ten 6R arms, one and 34 R-S-S-R loops, each on 21
/// time points.
#[must_use]
pub fn bench_descriptions() -> Vec<(&'static str, String)> {
    vec![
        ("chain_10.toml", chain(10, 20)),
        ("chain_100.toml", chain(100, 20)),
        ("arms_1x6.toml", arms(1, 6, 20)),
        ("arms_10x6.toml", arms(10, 6, 20)),
        ("rssr_loops_1.toml", rssr_loops(1, 20)),
        ("rssr_loops_34.toml", rssr_loops(34, 20)),
    ]
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// The files under `benches/scale/` are the families' text (rewritten with
    /// `UPDATE_EXPECT=1`), so the benchmark script measures what this module describes.
    #[test]
    fn the_committed_bench_descriptions_are_the_families() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../benches/scale");
        for (file, text) in super::bench_descriptions() {
            let path = dir.join(file);
            if std::env::var_os("UPDATE_EXPECT").is_some() {
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::write(&path, &text).unwrap();
            }
            let committed = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(committed == text, "{file} is stale: run with UPDATE_EXPECT=1");
        }
    }
}
