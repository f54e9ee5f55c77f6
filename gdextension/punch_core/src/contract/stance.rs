//! A boxer's stance: which side leads, and the guard it stands in.
//!
//! The character's pelvis is the game's (it faces its +Z, square to the target), so the stance is the upper body's:
//! the trunk turned so the lead shoulder comes forward and the rear shoulder back, the lead hand held a little ahead
//! of the face and the rear hand by the chin. Boxing coaches teach the rear shoulder "about 30-40 degrees back"
//! and the lead hand about 10 cm out from the face (ringsport.com.au, "Basic boxing stance"); the guard here turns
//! the trunk 30° and opens the lead arm 10° forward at the shoulder and 15° at the elbow, within every joint's
//! range. The southpaw's is the orthodox's mirror image.

use crate::contract::character::{DOF_COUNT, DOFS};
use crate::contract::mirror::mirror_targets;

/// Which side leads: the lead hand is the one nearer the opponent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Stance {
    /// The left hand leads (a right-handed boxer's stance).
    #[default]
    Orthodox,
    /// The right hand leads.
    Southpaw,
}

const fn deg(value: f32) -> f32 {
    value * std::f32::consts::PI / 180.0
}

/// The orthodox guard's joint targets (rad, from the square guard every joint's range is measured from, in action
/// order): the trunk turned 30° to the right (waist rotation, positive turning left), the left shoulder 10°
/// forward (flexion, positive swinging back) and the left elbow opened 15°; the right arm as in the square guard.
pub const ORTHODOX_GUARD_RAD: [f32; DOF_COUNT] = [0.0, deg(-30.0), 0.0, 0.0, 0.0, 0.0, deg(-10.0), 0.0, 0.0, deg(15.0)];

/// How much further forward the lead hand's targets lie than the square guard's reach volume (m): the stance's
/// guard holds the lead fist 0.10 m nearer the target (0.41 m ahead of the root against 0.30 m, measured in the
/// headless scene: tests/python/test_moves.py), so the lead hand's moves cover the volume moved forward by this
/// much and punch as far from their guard as a square guard's punch does; a target at the front of the square
/// volume already touches the lead fist. The rear hand's volume is the square guard's.
pub const LEAD_REACH_FORWARD_M: f32 = 0.10;

/// The high guard a block raises (rad, from the square guard, action order): the trunk square, each upper arm 20°
/// forward and 20° in toward the body, turned 30° across it, the elbows as bent as in the guard. It puts both fists
/// in front of the face, 0.23 m ahead of the head's centre line, 8 cm either side of it and 3 cm above the head's
/// centre (measured in the headless scene), the forearms rising to them: a straight punch at the head meets a glove or
/// a forearm first, as a boxer's high guard ("shell") takes it.
pub const HIGH_GUARD_RAD: [f32; DOF_COUNT] =
    [0.0, 0.0, deg(-20.0), deg(30.0), deg(20.0), 0.0, deg(-20.0), deg(-30.0), deg(-20.0), 0.0];

/// How far the high guard's fists rise per radian more of shoulder flexion, m/rad, over the first few centimetres
/// (measured in the headless scene, tests/godot/blocking.gd: 0.27 rad more raised them 5.8 cm).
pub const HIGH_GUARD_FIST_RISE_M_PER_RAD: f32 = 0.22;

/// The high guard for a character whose head sits `head_shift_m` higher on its neck than the simulated body's own
/// (`PunchCharacter.size_head`, an own rig's head): both shoulders flexed further forward (or back, for a lower head)
/// by as much as raises the fists that much, so the gloves stay in front of the face; within the shoulders' range.
pub fn high_guard_rad(head_shift_m: f32) -> [f32; DOF_COUNT] {
    let mut targets = HIGH_GUARD_RAD;
    if !head_shift_m.is_finite() {
        return targets;
    }
    for (target, dof) in targets.iter_mut().zip(&DOFS) {
        if dof.name.starts_with("shoulder_") && dof.name.ends_with("_flexion") {
            // Forward is negative.
            *target = (*target - head_shift_m / HIGH_GUARD_FIST_RISE_M_PER_RAD).clamp(dof.lower_rad, dof.upper_rad);
        }
    }
    targets
}

/// The action index of the degree of freedom `name` (`DOFS`).
fn dof_index(name: &str) -> Option<usize> {
    DOFS.iter().position(|dof| dof.name == name)
}

/// `guard` with the trunk turned at the waist toward an opponent `toward_rad` to the character's left (negative: its
/// right) of straight ahead, within the waist's range; a non-finite angle leaves it as it is. A block faces its
/// opponent so the shell meets the punch square on: the pelvis is the game's and faces where the game turned it,
/// which need not be the opponent.
pub fn turned_toward(mut guard: [f32; DOF_COUNT], toward_rad: f32) -> [f32; DOF_COUNT] {
    if let Some(index) = dof_index("waist_rotation")
        && toward_rad.is_finite()
    {
        guard[index] = toward_rad.clamp(DOFS[index].lower_rad, DOFS[index].upper_rad);
    }
    guard
}

/// A move's load: where the punching arm is drawn before the policy starts, from the guard the policy was trained
/// from (`punch train --load`, the policy file's `punch_start_load`). In the stance's guard the lead fist stands near
/// the line from its shoulder to the target and within 7-22 cm of it, so a lead hook trained from there lands the
/// shortest way, from the front, and a lead uppercut has no room below the target to rise from
/// (experiments/notebook.md, "Twelfth session"). Boxers load both: the hook with the elbow raised out to the side
/// and the trunk turned toward the punching hand, the fist near the shoulder's height, the uppercut with that
/// shoulder dipped and the fist dropped to the chest. Said for the right hand, as policies punch (a left-hand move's
/// load is its mirror image).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Load {
    /// The trunk turned 15° toward the punching side, the upper arm swung 35° back and raised 70° out to the side,
    /// turned 30° outward, the elbow opened 5°: from the southpaw guard the right fist stands at the shoulder's
    /// height, 14 cm outside it (measured in the headless scene).
    Hook,
    /// The trunk turned 10° toward the punching side and leaning 10° forward, the upper arm swung 55° back, the
    /// elbow bent 15° more: from the southpaw guard the right fist drops 30 cm, to the chest (1.21 m).
    Uppercut,
}

const HOOK_LOAD_SHIFT_RAD: [(&str, f32); 5] = [
    ("waist_rotation", deg(-15.0)),
    ("shoulder_r_flexion", deg(35.0)),
    ("shoulder_r_abduction", deg(-70.0)),
    ("shoulder_r_rotation", deg(-30.0)),
    ("elbow_r_extension", deg(5.0)),
];

const UPPERCUT_LOAD_SHIFT_RAD: [(&str, f32); 4] = [
    ("waist_rotation", deg(-10.0)),
    ("waist_flexion", deg(10.0)),
    ("shoulder_r_flexion", deg(55.0)),
    ("elbow_r_extension", deg(-15.0)),
];

impl Load {
    /// Every load, by the name a policy file and `punch train --load` give it.
    pub const ALL: [(&'static str, Load); 2] = [("hook", Load::Hook), ("uppercut", Load::Uppercut)];

    /// The load named `name`; None for a name that is none.
    pub fn from_name(name: &str) -> Option<Load> {
        Self::ALL.iter().find(|(known, _)| *known == name).map(|(_, load)| *load)
    }

    /// Its name (`ALL`).
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(_, load)| *load == self).map(|(name, _)| *name).unwrap_or_default()
    }

    /// How far each joint target moves from the guard (rad; the right arm punches).
    fn shift_rad(self) -> &'static [(&'static str, f32)] {
        match self {
            Load::Hook => &HOOK_LOAD_SHIFT_RAD,
            Load::Uppercut => &UPPERCUT_LOAD_SHIFT_RAD,
        }
    }

    /// `guard` (rad, action order) with the right arm loaded, within every joint's range.
    pub fn loaded(self, mut guard: [f32; DOF_COUNT]) -> [f32; DOF_COUNT] {
        for &(name, shift) in self.shift_rad() {
            if let Some(index) = dof_index(name) {
                guard[index] = (guard[index] + shift).clamp(DOFS[index].lower_rad, DOFS[index].upper_rad);
            }
        }
        guard
    }

    /// `guard` loaded for the move's hand: when `mirrored` (a left-hand move: the policy plays mirrored), the mirror
    /// image of the right hand's load.
    pub fn loaded_for(self, guard: [f32; DOF_COUNT], mirrored: bool) -> [f32; DOF_COUNT] {
        if mirrored { mirror_targets(&self.loaded(mirror_targets(&guard))) } else { self.loaded(guard) }
    }
}

impl Stance {
    /// The joint targets of this stance's guard (rad, action order).
    pub fn guard_targets(self) -> [f32; DOF_COUNT] {
        match self {
            Stance::Orthodox => ORTHODOX_GUARD_RAD,
            Stance::Southpaw => mirror_targets(&ORTHODOX_GUARD_RAD),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::character::DOFS;

    #[test]
    fn the_orthodox_guard_turns_the_left_side_forward_within_every_range() {
        let guard = Stance::Orthodox.guard_targets();
        for (target, dof) in guard.iter().zip(&DOFS) {
            assert!(dof.lower_rad < *target && *target < dof.upper_rad, "{} at {target}", dof.name);
        }
        let index = |name: &str| DOFS.iter().position(|d| d.name == name).expect("a DOF");
        assert!(guard[index("waist_rotation")] < 0.0, "the trunk turns right: the left shoulder comes forward");
        assert!(
            guard[index("shoulder_l_flexion")] < 0.0 && guard[index("elbow_l_extension")] > 0.0,
            "the lead hand out"
        );
        assert_eq!(guard[index("shoulder_r_flexion")], 0.0);
    }

    #[test]
    fn the_high_guard_is_its_own_mirror_image_within_every_range() {
        assert_eq!(mirror_targets(&HIGH_GUARD_RAD), HIGH_GUARD_RAD, "both arms rise alike");
        for (target, dof) in HIGH_GUARD_RAD.iter().zip(&DOFS) {
            assert!(dof.lower_rad < *target && *target < dof.upper_rad, "{} at {target}", dof.name);
        }
    }

    #[test]
    fn a_higher_head_raises_the_high_guard_by_flexing_both_shoulders_forward() {
        let index = |name: &str| DOFS.iter().position(|d| d.name == name).expect("a DOF");
        assert_eq!(high_guard_rad(0.0), HIGH_GUARD_RAD);
        assert_eq!(high_guard_rad(f32::NAN), HIGH_GUARD_RAD);
        let raised = high_guard_rad(0.06);
        assert_eq!(mirror_targets(&raised), raised, "both arms rise alike");
        for name in ["shoulder_r_flexion", "shoulder_l_flexion"] {
            let more = HIGH_GUARD_RAD[index(name)] - raised[index(name)];
            assert!((more - 0.06 / HIGH_GUARD_FIST_RISE_M_PER_RAD).abs() < 1e-6, "{name}: {more}");
        }
        let changed = (0..DOF_COUNT).filter(|&i| raised[i] != HIGH_GUARD_RAD[i]).count();
        assert_eq!(changed, 2, "only the shoulders' flexion");
        for (target, dof) in high_guard_rad(10.0).iter().zip(&DOFS) {
            assert!(dof.lower_rad <= *target && *target <= dof.upper_rad, "{} at {target}", dof.name);
        }
    }

    #[test]
    fn a_guard_turned_toward_an_opponent_turns_only_the_waist_within_its_range() {
        let index = |name: &str| DOFS.iter().position(|d| d.name == name).expect("a DOF");
        let waist = index("waist_rotation");
        let left = turned_toward(HIGH_GUARD_RAD, 0.3);
        assert_eq!(left[waist], 0.3, "positive turns the trunk left");
        assert_eq!((0..DOF_COUNT).filter(|&i| left[i] != HIGH_GUARD_RAD[i]).count(), 1, "only the waist turns");
        assert_eq!(mirror_targets(&turned_toward(HIGH_GUARD_RAD, -0.3)), left, "the right is the left's mirror image");
        assert_eq!(turned_toward(HIGH_GUARD_RAD, 3.0)[waist], DOFS[waist].upper_rad, "behind: as far as it turns");
        assert_eq!(turned_toward(HIGH_GUARD_RAD, f32::NAN), HIGH_GUARD_RAD);
    }

    #[test]
    fn a_load_moves_only_the_waist_and_the_punching_arm_within_every_range_and_mirrors_for_the_left_hand() {
        let index = |name: &str| DOFS.iter().position(|d| d.name == name).expect("a DOF");
        let guard = Stance::Southpaw.guard_targets();
        for (name, load) in Load::ALL {
            assert_eq!(Load::from_name(name), Some(load));
            assert_eq!(load.name(), name);
            let loaded = load.loaded(guard);
            for (i, (target, dof)) in loaded.iter().zip(&DOFS).enumerate() {
                assert!(dof.lower_rad <= *target && *target <= dof.upper_rad, "{name}: {} at {target}", dof.name);
                if *target != guard[i] {
                    assert!(dof.name.starts_with("waist_") || dof.name.contains("_r_"), "{name} moves {}", dof.name);
                }
            }
            assert!(loaded[index("waist_rotation")] < guard[index("waist_rotation")], "{name}: turned to the right");
            assert!(loaded[index("shoulder_r_flexion")] > guard[index("shoulder_r_flexion")], "{name}: the arm back");
            // The orthodox lead (left) hand's load is the mirror image of the southpaw's right.
            let orthodox = Stance::Orthodox.guard_targets();
            assert_eq!(load.loaded_for(orthodox, true), mirror_targets(&loaded), "{name}");
            assert_eq!(load.loaded_for(guard, false), loaded, "{name}");
        }
        assert!(Load::Hook.loaded(guard)[index("shoulder_r_abduction")] < -1.0, "the hook's elbow out to the side");
        assert_eq!(Load::from_name("swing"), None);
    }

    #[test]
    fn the_southpaw_guard_is_the_orthodox_mirrored() {
        let (orthodox, southpaw) = (Stance::Orthodox.guard_targets(), Stance::Southpaw.guard_targets());
        let index = |name: &str| DOFS.iter().position(|d| d.name == name).expect("a DOF");
        assert_eq!(southpaw[index("waist_rotation")], -orthodox[index("waist_rotation")]);
        assert_eq!(southpaw[index("shoulder_r_flexion")], orthodox[index("shoulder_l_flexion")]);
        assert_eq!(southpaw[index("elbow_r_extension")], orthodox[index("elbow_l_extension")]);
        assert_eq!(mirror_targets(&southpaw), orthodox);
    }
}
