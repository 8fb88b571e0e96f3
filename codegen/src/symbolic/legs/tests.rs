//! Which legs are reduced: the shipped Stewart platform's six, and none whose bodies carry
//! anything else.

use super::super::Symbolic;
use crate::blocks::Blocks;
use crate::testing::{load_example, load_toml};

/// The drivers of the legs a system reduced, by name.
fn reduced(text: &str) -> Vec<String> {
    let mech = load_toml(text);
    let sys = Symbolic::build(&mech).expect("the system builds");
    sys.legs.iter().map(|l| mech.drivers[l.driver].name.clone()).collect()
}

#[test]
fn the_shipped_platforms_six_legs_are_reduced_and_its_pose_is_a_block_of_seven() {
    let mech = load_example("inputs/stewart.toml");
    let sys = Symbolic::build(&mech).expect("the system builds");
    let names: Vec<&str> = sys.legs.iter().map(|l| mech.drivers[l.driver].name.as_str()).collect();
    assert_eq!(names, ["leg1", "leg2", "leg3", "leg4", "leg5", "leg6"]);
    // The legs' ends are on the prismatic axes (U at the cylinder's origin, S at the rod's):
    // v0 = 0, so |S − U| = s, and the row's scale is the home length.
    let platform = mech.bodies.iter().find(|b| b.name == "platform").expect("a platform").r;
    for (k, l) in sys.legs.iter().enumerate() {
        assert_eq!((l.leg.along, l.leg.base, l.leg.branch), (0.0, 0.0, 1.0));
        let joint = |name: String| mech.joints.iter().find(|j| j.name == name).expect("a joint");
        let u = joint(format!("U{}", k + 1)).point_i;
        let s = platform + joint(format!("S{}", k + 1)).point_j;
        // The description's initial estimates are the assembled home pose (to its 1e-12
        // tolerance), the frames unrotated: |S − U| from the joint points to round-off.
        assert!((l.leg.length - (s - u).norm()).abs() < 1e-12, "{}", l.leg.length);
    }
    let sizes = Blocks::of(&sys, &mech).sizes();
    assert_eq!(sizes.get(&7), Some(&1), "{sizes:?}");
}

#[test]
fn a_leg_whose_cylinder_carries_another_joint_keeps_its_driver_row() {
    let path = crate::testing::example("inputs/stewart.toml");
    let text = std::fs::read_to_string(path).expect("the shipped description");
    // A probe hinged to cylinder 1 and turned by a driver of its own: the system stays
    // square, but cylinder 1 now carries a third joint, so leg 1 is no leg.
    let probe = "[[bodies]]\nname = \"probe\"\nr = [0.9659258262890683, -0.25881904510252074, \
                 0.0]\n[[joints]]\nname = \"hinge\"\ntype = \"revolute\"\nbody_i = \
                 \"cylinder1\"\nbody_j = \"probe\"\npoint_i = [0.0, 0.0, 0.0]\npoint_j = [0.0, \
                 0.0, 0.0]\naxis_i = [0.0, 0.0, 1.0]\naxis_j = [0.0, 0.0, 1.0]\nref_i = [1.0, \
                 0.0, 0.0]\nref_j = [1.0, 0.0, 0.0]\n[[drivers]]\nname = \"probe_turn\"\njoint = \
                 \"hinge\"\nmotion = \"rotation\"\nlaw = { start = 0.0, velocity = 1.0, \
                 acceleration = 0.0 }\n";
    assert_eq!(reduced(&format!("{text}\n{probe}")), ["leg2", "leg3", "leg4", "leg5", "leg6"]);
    // Leg 1's driver row still involves its cylinder and rod: the platform's pose is no
    // longer a block of its own.
    let mech = load_toml(&format!("{text}\n{probe}"));
    let sys = Symbolic::build(&mech).expect("the system builds");
    assert_eq!(Blocks::of(&sys, &mech).sizes().get(&7), None);
}
