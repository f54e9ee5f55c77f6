use glam::{Quat, Vec3};

use super::*;
use crate::rig::bone_map::map_bones;
use crate::rig::transform::TransformError;

/// A humanoid in a T-pose (or an A-pose, arms `arm_drop_rad` below horizontal), facing +Z, +X its left, with
/// its bones' rest rotations in one of several axis conventions: 0 identity, 1 each bone's +Y toward its child
/// with a roll, 2 +X toward its child.
fn humanoid(arm_drop_rad: f32, convention: u32) -> (Vec<&'static str>, Vec<i32>, Vec<(Quat, Vec3)>) {
    let mut bones: Vec<(&str, i32, Vec3)> = vec![
        ("Hips", -1, Vec3::new(0.0, 1.0, 0.0)),
        ("Spine", 0, Vec3::new(0.0, 1.1, 0.0)),
        ("Spine1", 1, Vec3::new(0.0, 1.22, 0.0)),
        ("Spine2", 2, Vec3::new(0.0, 1.34, 0.0)),
        ("Neck", 3, Vec3::new(0.0, 1.5, 0.0)),
        ("Head", 4, Vec3::new(0.0, 1.6, 0.0)),
    ];
    for (sign, names) in [
        (1.0, ["LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "LeftHandMiddle1"]),
        (-1.0, ["RightShoulder", "RightArm", "RightForeArm", "RightHand", "RightHandMiddle1"]),
    ] {
        let out = Vec3::new(sign * arm_drop_rad.cos(), -arm_drop_rad.sin(), 0.0);
        let shoulder = Vec3::new(sign * 0.05, 1.45, 0.0);
        let arm = Vec3::new(sign * 0.18, 1.45, 0.0);
        let parent = bones.len() as i32;
        bones.push((names[0], 3, shoulder));
        bones.push((names[1], parent, arm));
        bones.push((names[2], parent + 1, arm + 0.28 * out));
        bones.push((names[3], parent + 2, arm + 0.55 * out));
        bones.push((names[4], parent + 3, arm + 0.64 * out));
    }
    for (sign, names) in [(1.0, ["LeftUpLeg", "LeftLeg", "LeftFoot"]), (-1.0, ["RightUpLeg", "RightLeg", "RightFoot"])]
    {
        let parent = bones.len() as i32;
        bones.push((names[0], 0, Vec3::new(sign * 0.1, 0.95, 0.0)));
        bones.push((names[1], parent, Vec3::new(sign * 0.1, 0.5, 0.0)));
        bones.push((names[2], parent + 1, Vec3::new(sign * 0.1, 0.08, 0.0)));
    }
    let child_of = |i: usize| bones.iter().position(|b| b.1 == i as i32);
    let rest = (0..bones.len())
        .map(|i| {
            let toward = child_of(i).map(|c| bones[c].2 - bones[i].2).unwrap_or(Vec3::Y).normalize();
            let roll = 0.3 + i as f32;
            let rotation = match convention {
                0 => Quat::IDENTITY,
                1 => Quat::from_axis_angle(toward, roll) * Quat::from_rotation_arc(Vec3::Y, toward),
                _ => Quat::from_axis_angle(toward, roll) * Quat::from_rotation_arc(Vec3::X, toward),
            };
            (rotation, bones[i].2)
        })
        .collect();
    (bones.iter().map(|b| b.0).collect(), bones.iter().map(|b| b.1).collect(), rest)
}

/// The simulated body's rest geometry as the addon's scene has it: arms 35 degrees forward of straight down,
/// elbows bent 120 degrees (forearm bodies with -Y toward the fist).
fn geometry() -> CharacterGeometry {
    let upper = Quat::from_rotation_x(-35f32.to_radians());
    let fore = Quat::from_rotation_x(-155f32.to_radians());
    CharacterGeometry {
        rest_rotations: [Quat::IDENTITY, Quat::IDENTITY, upper, fore, upper, fore, Quat::IDENTITY],
        fist_offsets: [Vec3::new(0.0, -0.155, 0.0); 2],
        fist_radius_m: 0.045,
        joint_anchors: [
            (Vec3::new(0.0, 0.07, 0.0), Vec3::new(0.0, -0.27, 0.0)),
            (Vec3::new(-0.18, 0.09, 0.0), Vec3::new(0.0, 0.14, 0.0)),
            (Vec3::new(0.0, -0.14, 0.0), Vec3::new(0.0, 0.13, 0.0)),
            (Vec3::new(0.18, 0.09, 0.0), Vec3::new(0.0, 0.14, 0.0)),
            (Vec3::new(0.0, -0.14, 0.0), Vec3::new(0.0, 0.13, 0.0)),
        ],
        bag_radius_m: 0.0,
        bag_height_m: 0.0,
        bag_mass_kg: 0.0,
        root_rotation: Quat::IDENTITY,
        root_position: Vec3::ZERO,
        pelvis_rest_position: Vec3::ZERO,
    }
}

fn poser(arm_drop_rad: f32, convention: u32) -> (SkeletonPoser, Vec<i32>, Vec<(Quat, Vec3)>, BoneMap) {
    let (names, parents, rest) = humanoid(arm_drop_rad, convention);
    let map = map_bones(&names, &parents).expect("mapped");
    let frames = BodyFrames::from_geometry(&geometry()).expect("frames");
    let fists = rig_fists(&map, &parents, &rest, [&[], &[]]);
    (SkeletonPoser::new(&map, &parents, &rest, fists, frames).expect("poser"), parents, rest, map)
}

fn rest_local(parents: &[i32], rest: &[(Quat, Vec3)], bone: usize) -> Quat {
    match usize::try_from(parents[bone]) {
        Ok(p) => rest[p].0.inverse() * rest[bone].0,
        Err(_) => rest[bone].0,
    }
}

/// Global rotations after writing `locals` over the rest pose.
fn globals(poser: &SkeletonPoser, parents: &[i32], rest: &[(Quat, Vec3)], locals: &[Quat]) -> Vec<Quat> {
    let mut local: Vec<Quat> = (0..rest.len()).map(|b| rest_local(parents, rest, b)).collect();
    for (bone, q) in poser.written_bones().zip(locals) {
        local[bone] = *q;
    }
    let mut global = vec![Quat::IDENTITY; rest.len()];
    for b in 0..rest.len() {
        global[b] = match usize::try_from(parents[b]) {
            Ok(p) => global[p] * local[b],
            Err(_) => local[b],
        };
    }
    global
}

/// The angle between two rotations, precise near zero (unlike `2 acos(dot)` in f32).
fn angle(a: Quat, b: Quat) -> f32 {
    let d = a.inverse() * b;
    2.0 * d.xyz().length().atan2(d.w.abs())
}

fn some_bodies(seed: f32) -> BodyRotations {
    let r = |k: f32| {
        Quat::from_euler(
            glam::EulerRot::YXZ,
            0.7 * (seed + k).sin(),
            1.1 * (2.0 * seed + k).cos(),
            0.4 * (seed * k).sin(),
        )
    };
    let torso = r(0.3) * Quat::from_rotation_y(0.1);
    BodyRotations { torso, head: torso, upper_arm: [r(1.0), r(2.0)], forearm: [r(3.0), r(4.0)] }
}

#[test]
fn frame_points_y_along_the_direction_and_z_toward_the_hint() {
    let q = frame(Vec3::new(0.0, -2.0, 1.0), Vec3::Z).expect("valid");
    assert!((q * Vec3::Y - Vec3::new(0.0, -2.0, 1.0).normalize()).length() < 1e-6);
    assert!((q * Vec3::Z).dot(Vec3::Z) > 0.0 && (q * Vec3::Z).dot(q * Vec3::Y).abs() < 1e-6);
    assert!(frame(Vec3::Z, Vec3::Z).is_none() && frame(Vec3::ZERO, Vec3::Z).is_none());
}

#[test]
fn the_rig_frame_is_read_from_the_bones() {
    for convention in 0..3 {
        let (poser, ..) = poser(0.0, convention);
        assert!(angle(poser.rig_frame(), Quat::IDENTITY) < 1e-5, "a rig facing +Z with +X its left");
    }
    // The same rig turned half round: its frame turns with it.
    let (names, parents, rest) = humanoid(0.0, 1);
    let turn = Quat::from_rotation_y(std::f32::consts::PI);
    let turned: Vec<(Quat, Vec3)> = rest.iter().map(|(q, p)| (turn * *q, turn * *p)).collect();
    let map = map_bones(&names, &parents).expect("valid");
    let fists = rig_fists(&map, &parents, &turned, [&[], &[]]);
    let poser =
        SkeletonPoser::new(&map, &parents, &turned, fists, BodyFrames::from_geometry(&geometry()).expect("valid"))
            .expect("valid");
    assert!(angle(poser.rig_frame(), turn) < 1e-5);
}

#[test]
fn bones_point_along_the_simulated_segments_in_any_axis_convention_and_rest_pose() {
    let frames = BodyFrames::from_geometry(&geometry()).expect("valid");
    for drop in [0.0, 45f32.to_radians()] {
        let mut deltas: Vec<Vec<Quat>> = Vec::new();
        for convention in 0..3 {
            let (poser, parents, rest, map) = poser(drop, convention);
            let bodies = some_bodies(0.7);
            let locals = poser.pose(&bodies, rest[map.hips].0, |b| rest_local(&parents, &rest, b));
            let g = globals(&poser, &parents, &rest, &locals);
            for (i, side) in [Side::Right, Side::Left].into_iter().enumerate() {
                let arm = map.arm(side);
                for (bone, child, body, body_frame) in [
                    (arm.upper_arm, arm.forearm, bodies.upper_arm[i], frames.upper_arm[i]),
                    (arm.forearm, arm.hand, bodies.forearm[i], frames.forearm[i]),
                ] {
                    let rest_dir = (rest[child].1 - rest[bone].1).normalize();
                    let now = g[bone] * rest[bone].0.inverse() * rest_dir;
                    let segment = body * body_frame * Vec3::Y;
                    assert!((now - segment).length() < 1e-4, "drop {drop} convention {convention} bone {bone}");
                }
            }
            // The chest faces where the simulated torso does.
            let chest = map.chest();
            let chest_front = g[chest] * rest[chest].0.inverse() * Vec3::Z;
            assert!((chest_front - bodies.torso * Vec3::Z).length() < 1e-4);
            deltas.push(poser.written_bones().map(|b| g[b] * rest[b].0.inverse()).collect());
        }
        // The turn of every bone from its rest is the same whatever way its axes point.
        for other in &deltas[1..] {
            for (a, b) in deltas[0].iter().zip(other) {
                assert!(angle(*a, *b) < 1e-4, "drop {drop}: {} rad apart", angle(*a, *b));
            }
        }
    }
}

#[test]
fn the_elbow_bends_as_a_hinge_with_no_twist_between_upper_arm_and_forearm() {
    let (poser, parents, rest, map) = poser(0.0, 1);
    // Arms as the simulated elbow allows: the forearm turned from its rest relative to the upper arm about
    // the elbow's axis (the character's X at rest) only.
    let g0 = geometry().rest_rotations;
    let mut bodies = some_bodies(1.3);
    for (i, (u, f)) in [(2, 3), (4, 5)].into_iter().enumerate() {
        let hinge = Quat::from_axis_angle(g0[u].inverse() * Vec3::X, 0.4 + i as f32 * 0.3);
        bodies.forearm[i] = bodies.upper_arm[i] * hinge * g0[u].inverse() * g0[f];
    }
    let locals = poser.pose(&bodies, rest[map.hips].0, |b| rest_local(&parents, &rest, b));
    let g = globals(&poser, &parents, &rest, &locals);
    for side in [Side::Right, Side::Left] {
        let arm = map.arm(side);
        // In a T-pose both bones lie on one line: the forearm's turn relative to the upper arm is about an
        // axis perpendicular to the upper arm (a hinge), never about the arm itself.
        let relative = (g[arm.upper_arm] * rest[arm.upper_arm].0.inverse()).inverse()
            * (g[arm.forearm] * rest[arm.forearm].0.inverse());
        let (axis, turned) = relative.to_axis_angle();
        let along = (rest[arm.forearm].1 - rest[arm.upper_arm].1).normalize();
        if turned > 1e-3 {
            assert!(axis.dot(along).abs() < 1e-3, "{side:?}: twist about the arm {}", axis.dot(along));
        }
    }
}

#[test]
fn at_the_equivalent_pose_the_rig_keeps_its_rest_and_the_hand_stays_straight() {
    for convention in 0..3 {
        let (poser, parents, rest, map) = poser(0.3, convention);
        let frames = BodyFrames::from_geometry(&geometry()).expect("valid");
        // Body rotations whose anatomical frames are the rig's rest frames.
        let f = |bone: usize, child: usize| frame(rest[child].1 - rest[bone].1, Vec3::Z).expect("valid");
        let bodies = BodyRotations {
            torso: frames.torso.inverse(),
            head: frames.head.inverse(),
            upper_arm: [
                f(map.right.upper_arm, map.right.forearm) * frames.upper_arm[0].inverse(),
                f(map.left.upper_arm, map.left.forearm) * frames.upper_arm[1].inverse(),
            ],
            forearm: [
                f(map.right.forearm, map.right.hand) * frames.forearm[0].inverse(),
                f(map.left.forearm, map.left.hand) * frames.forearm[1].inverse(),
            ],
        };
        let locals = poser.pose(&bodies, rest[map.hips].0, |b| rest_local(&parents, &rest, b));
        for (bone, local) in poser.written_bones().zip(&locals) {
            assert!(angle(*local, rest_local(&parents, &rest, bone)) < 1e-4, "convention {convention} bone {bone}");
        }
    }
}

#[test]
fn the_spine_shares_the_chest_turn_evenly_and_the_chest_lands_on_its_target() {
    let (poser, parents, rest, map) = poser(0.0, 2);
    let bodies = some_bodies(2.1);
    let hips = Quat::from_rotation_y(0.2) * rest[map.hips].0;
    let locals = poser.pose(&bodies, hips, |b| rest_local(&parents, &rest, b));
    let mut turns = Vec::new();
    let mut parent = hips;
    for (k, &bone) in map.spine.iter().enumerate() {
        let local = locals[k];
        turns.push(angle(local, rest_local(&parents, &rest, bone)));
        parent *= local;
    }
    let chest = map.chest();
    assert!((parent * rest[chest].0.inverse() * Vec3::Z - bodies.torso * Vec3::Z).length() < 1e-4);
    for t in &turns {
        assert!((t - turns[0]).abs() < 1e-4, "{turns:?}");
    }
    // The legs are never written; the neck and the head keep the animation on the chest (no snap here).
    let written: Vec<usize> = poser.written_bones().collect();
    assert!(!written.contains(&map.hips) && written.contains(&map.head));
    assert_eq!(written.len(), 3 + 2 * 4 + 2);
    let globals = globals(&poser, &parents, &rest, &locals);
    let head_on_chest = |g: &[Quat]| g[map.chest()].inverse() * g[map.head];
    assert!(angle(head_on_chest(&globals), rest[map.chest()].0.inverse() * rest[map.head].0) < 1e-4);
}

#[test]
fn the_head_snaps_as_the_simulated_head_turns_on_its_neck_shared_by_the_neck_bones() {
    let (poser, parents, rest, map) = poser(0.3, 1);
    let still = some_bodies(0.7);
    // The simulated head turned 30 degrees about a tilted axis away from the chest (in the skeleton's space).
    let snap = Quat::from_axis_angle(Vec3::new(1.0, 0.4, -0.3).normalize(), 30f32.to_radians());
    let snapped = BodyRotations { head: snap * still.head, ..still };
    let hips = rest[map.hips].0;
    let animated = |b| rest_local(&parents, &rest, b);
    let before = globals(&poser, &parents, &rest, &poser.pose(&still, hips, animated));
    let after = globals(&poser, &parents, &rest, &poser.pose(&snapped, hips, animated));
    // The head turns by the whole snap, the neck (halfway up) by half of it; nothing else moves.
    assert!(angle(after[map.head], snap * before[map.head]) < 1e-4);
    let neck = map.neck.expect("the humanoid has a neck");
    let half = Quat::from_axis_angle(Vec3::new(1.0, 0.4, -0.3).normalize(), 15f32.to_radians());
    assert!(angle(after[neck], half * before[neck]) < 1e-4);
    for bone in poser.written_bones().filter(|&b| b != map.head && b != neck) {
        assert!(angle(after[bone], before[bone]) < 1e-5, "bone {bone}");
    }
}

#[test]
fn blend_weights_ease_in_and_out_without_steps() {
    let mut blend = Blend::default();
    let dt = 1.0 / 120.0;
    let mut weights = vec![blend.weight()];
    for frame in 0..60 {
        weights.push(blend.advance(frame < 30, dt, 0.1, 0.2));
    }
    assert_eq!(weights[0], 0.0);
    assert!((weights[15] - 1.0).abs() < 1e-6 && weights[60] == 0.0);
    let steps: Vec<f32> = weights.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    // Smoothstep: the largest step is 1.5x the linear one, and the first and last steps are small.
    assert!(steps.iter().all(|&s| s <= 1.5 * dt / 0.1 + 1e-5));
    assert!(steps[0] < 0.03 && steps[12] < 0.03);
    assert_eq!(Blend::default().advance(true, dt, 0.0, 0.0), 1.0);
}

#[test]
fn a_rig_without_length_is_refused_by_name() {
    let (names, parents, mut rest) = humanoid(0.0, 0);
    let map = map_bones(&names, &parents).expect("valid");
    rest[map.right.forearm].1 = rest[map.right.upper_arm].1;
    let fists = rig_fists(&map, &parents, &rest, [&[], &[]]);
    let error =
        SkeletonPoser::new(&map, &parents, &rest, fists, BodyFrames::from_geometry(&geometry()).expect("valid"))
            .expect_err("refused");
    assert!(error.to_string().contains("Right upper arm"), "{error}");
}

#[test]
fn the_fist_is_three_quarters_to_the_knuckles_whether_fingers_start_at_the_wrist_or_at_the_knuckles() {
    let at = |x: f32, z: f32| (Quat::IDENTITY, Vec3::new(x, 1.4, z));
    // Elbow (0), wrist (1) 0.28 m on along +X; fingers rooted at the knuckles 0.10 m on (Mixamo-like) ...
    let direct = [at(0.0, 0.0), at(0.28, 0.0), at(0.38, -0.02), at(0.38, 0.02)];
    let fist = rig_fist(&[-1, 0, 1, 1], &direct, 1, 0);
    assert!((fist - Vec3::new(0.355, 1.4, 0.0)).length() < 1e-5, "{fist}");
    // ... or through metacarpals that start at the wrist (MakeHuman-like).
    let metacarpals = [at(0.0, 0.0), at(0.28, 0.0), at(0.30, -0.02), at(0.38, -0.02), at(0.30, 0.02), at(0.38, 0.02)];
    let fist = rig_fist(&[-1, 0, 1, 2, 1, 4], &metacarpals, 1, 0);
    assert!((fist - Vec3::new(0.355, 1.4, 0.0)).length() < 1e-5, "{fist}");
    // A thumb near the wrist and one bone for the four fingers (CMU-like): the fingers count four times.
    let one_finger_bone = [at(0.0, 0.0), at(0.28, 0.0), at(0.30, 0.03), at(0.38, 0.0)];
    let fist = rig_fist(&[-1, 0, 1, 1], &one_finger_bone, 1, 0);
    let knuckles = Vec3::new((4.0 * 0.38 + 0.30) / 5.0, 1.4, 0.006);
    assert!(
        (fist - (Vec3::new(0.28, 1.4, 0.0) + 0.75 * (knuckles - Vec3::new(0.28, 1.4, 0.0)))).length() < 1e-5,
        "{fist}"
    );
    // No fingers: a quarter of the forearm on.
    let fist = rig_fist(&[-1, 0], &direct[..2], 1, 0);
    assert!((fist - Vec3::new(0.35, 1.4, 0.0)).length() < 1e-5, "{fist}");
}

#[test]
fn the_skin_moves_the_fist_across_the_hand_but_not_along_it() {
    let wrist = Vec3::new(0.28, 1.4, 0.0);
    let fist = Vec3::new(0.355, 1.4, 0.0);
    // A hand's skin whose middle lies 2 cm toward -Z (the little finger's side) and 5 cm further on than the fist:
    // the fist moves the 2 cm across, not along.
    let skin: Vec<Vec3> = (0..40)
        .map(|i| Vec3::new(0.405 + 0.01 * ((i % 5) as f32 - 2.0), 1.4 + 0.001 * ((i % 3) as f32 - 1.0), -0.02))
        .collect();
    let moved = across_hand_skin(fist, wrist, &skin);
    assert!((moved - Vec3::new(0.355, 1.4, -0.02)).length() < 1e-4, "{moved}");
    // Too few points (no skinned mesh): the bones' fist.
    assert_eq!(across_hand_skin(fist, wrist, &skin[..MIN_HAND_SKIN_POINTS - 1]), fist);
    assert_eq!(across_hand_skin(fist, wrist, &[]), fist);
}

#[test]
fn a_broken_rest_is_found_on_the_bones_the_pose_reads_and_named_with_its_cause() {
    let (names, parents, _) = humanoid(0.0, 1);
    let map = map_bones(&names, &parents).expect("valid");
    let bone = |name: &str| names.iter().position(|n| *n == name).expect("a bone");
    let mut broken = vec![None; names.len()];
    assert_eq!(broken_rest(&map, &parents, &broken), None);
    // A leg does not matter; a finger below the hand, the hips above everything and an upper arm do.
    broken[bone("LeftFoot")] = Some(TransformError::NoSize);
    assert_eq!(broken_rest(&map, &parents, &broken), None);
    broken[bone("RightHandMiddle1")] = Some(TransformError::NotFinite);
    assert_eq!(broken_rest(&map, &parents, &broken), Some((bone("RightHandMiddle1"), TransformError::NotFinite)));
    broken[bone("RightArm")] = Some(TransformError::NotFinite);
    assert_eq!(broken_rest(&map, &parents, &broken), Some((bone("RightArm"), TransformError::NotFinite)));
    broken[bone("Hips")] = Some(TransformError::NoSize);
    let error = PoseError::BrokenRest { bone: 0, cause: TransformError::NoSize };
    assert_eq!(broken_rest(&map, &parents, &broken), Some((0, TransformError::NoSize)));
    assert_eq!(error.to_string(), "bone 0's rest has no size (a scale of 0)");
    // A parent list with a cycle does not hang it.
    let mut looped = parents.clone();
    looped[0] = bone("Head") as i32;
    let _ = broken_rest(&map, &looped, &broken);
}

proptest::proptest! {
    /// Whatever the simulated bodies' rotations and the animation's pose (unit rotations: the modifier checks what
    /// the engine gives before it asks), the pose is made without a panic (glam's asserts are on in tests) and is
    /// made of unit rotations.
    #[test]
    fn any_unit_rotations_pose_the_skeleton_without_a_panic(
        angles in proptest::collection::vec(-10.0f32..10.0, 24),
        degenerate_spine in proptest::bool::ANY,
    ) {
        let (poser, parents, rest, map) = poser(0.3, 1);
        let q = |i: usize| {
            Quat::from_euler(glam::EulerRot::YXZ, angles[3 * i], angles[3 * i + 1], angles[3 * i + 2]).normalize()
        };
        let bodies = BodyRotations { torso: q(0), head: q(5), upper_arm: [q(1), q(2)], forearm: [q(3), q(4)] };
        // The chest's animated turn exactly opposite the target's (a half turn to share) or any other.
        let animated = |b: usize| if degenerate_spine { Quat::from_rotation_y(std::f32::consts::PI) } else { q(5 + b % 3) };
        let locals = poser.pose(&bodies, q(7) * rest[map.hips].0, animated);
        for local in locals {
            proptest::prop_assert!(local.is_finite() && local.is_normalized());
        }
        let _ = parents;
    }
}

#[test]
fn the_crown_is_read_from_the_heads_skin_else_from_a_head_top_bone() {
    let (names, mut parents, mut rest) = humanoid(0.0, 1);
    let map = map_bones(&names, &parents).expect("mapped");
    // Shoulder joints (the upper arms' heads) at 1.45 m, the head bone at 1.6 m: a skull whose top is 1.78 m high.
    let skin: Vec<Vec3> = (0..40).map(|i| Vec3::new(0.0, 1.6 + 0.18 * (i as f32 / 39.0), 0.05)).collect();
    let crown = rig_shoulder_to_crown(&map, &parents, &rest, &skin, 1.0).expect("from the skin");
    assert!((crown - 0.33).abs() < 1e-5, "{crown}");
    // In centimetres, as some imports are: the scale brings it back.
    let in_cm: Vec<(Quat, Vec3)> = rest.iter().map(|(q, p)| (*q, 100.0 * *p)).collect();
    let cm_skin: Vec<Vec3> = skin.iter().map(|p| 100.0 * *p).collect();
    let crown = rig_shoulder_to_crown(&map, &parents, &in_cm, &cm_skin, 0.01).expect("from the skin");
    assert!((crown - 0.33).abs() < 1e-4, "{crown}");
    // No skin and no bone above the head: nothing to size it by.
    assert_eq!(rig_shoulder_to_crown(&map, &parents, &rest, &skin[..MIN_HEAD_SKIN_POINTS - 1], 1.0), None);
    // A head-top bone (Mixamo's HeadTop_End) 0.2 m above the head.
    parents.push(map.head as i32);
    rest.push((Quat::IDENTITY, Vec3::new(0.0, 1.8, 0.0)));
    let crown = rig_shoulder_to_crown(&map, &parents, &rest, &[], 1.0).expect("from the bone");
    assert!((crown - 0.35).abs() < 1e-5, "{crown}");
}
