use glam::{Quat, Vec3};

use super::*;
use crate::rig::bone_map::map_bones;

/// Bone names, parents and global rest positions.
type Bones = Vec<(String, i32, Vec3)>;
/// Bone names, parents and global rest rotations and positions.
type Rig = (Vec<String>, Vec<i32>, Vec<(Quat, Vec3)>);

/// A humanoid in a T-pose facing +Z (+X its left) with five-fingered hands, palms down, thumbs forward. Each
/// finger has three bones and bends `rest_curl_rad` at each joint at rest; with `metacarpals` the four fingers
/// start from metacarpals at the wrist (MakeHuman), and `names` picks "mixamo" or "makehuman" finger names.
fn humanoid(rest_curl_rad: f32, metacarpals: bool, names: &str) -> Bones {
    let mut bones: Bones = vec![
        ("Hips".into(), -1, Vec3::new(0.0, 1.0, 0.0)),
        ("Spine".into(), 0, Vec3::new(0.0, 1.15, 0.0)),
        ("Spine2".into(), 1, Vec3::new(0.0, 1.34, 0.0)),
        ("Neck".into(), 2, Vec3::new(0.0, 1.5, 0.0)),
        ("Head".into(), 3, Vec3::new(0.0, 1.6, 0.0)),
    ];
    for (sign, side) in [(1.0f32, "Left"), (-1.0, "Right")] {
        let at = |x: f32, y: f32, z: f32| Vec3::new(sign * x, y, z);
        let top = bones.len() as i32;
        bones.push((format!("{side}Shoulder"), 2, at(0.05, 1.45, 0.0)));
        bones.push((format!("{side}Arm"), top, at(0.18, 1.45, 0.0)));
        bones.push((format!("{side}ForeArm"), top + 1, at(0.46, 1.45, 0.0)));
        bones.push((format!("{side}Hand"), top + 2, at(0.73, 1.45, 0.0)));
        let hand = top + 3;
        let wrist = at(0.73, 1.45, 0.0);
        let fingers = ["Thumb", "Index", "Middle", "Ring", "Pinky"];
        for (f, finger) in fingers.iter().enumerate() {
            let thumb = f == 0;
            let (root, out) = if thumb {
                (wrist + at(0.02, -0.01, 0.03), at(1.0, 0.0, 1.0).normalize())
            } else {
                (wrist + at(0.09, 0.0, 0.05 - 0.02 * f as f32), at(1.0, 0.0, 0.0))
            };
            let mut parent = hand;
            if metacarpals && !thumb {
                bones.push((format!("metacarpal{f}.{}", &side[..1]), hand, wrist + at(0.01, 0.0, 0.0)));
                parent = bones.len() as i32 - 1;
            }
            let mut head = root;
            let mut direction = out;
            for (k, length) in [0.045, 0.025, 0.02].into_iter().enumerate() {
                let name = match names {
                    "makehuman" => format!("finger{}-{}.{}", f + 1, k + 1, &side[..1]),
                    _ => format!("{side}Hand{finger}{}", k + 1),
                };
                bones.push((name, parent, head));
                parent = bones.len() as i32 - 1;
                // Rest curl: toward the palm (down), about the knuckle line.
                let axis = direction.cross(-Vec3::Y).normalize();
                direction = Quat::from_axis_angle(axis, if thumb { 0.0 } else { rest_curl_rad }) * direction;
                head += length * direction;
            }
        }
    }
    bones
}

/// The rig's global rest: turned by `turn`, each bone's rotation in an axis convention (0 identity, 1 +Y toward
/// its child with a roll, 2 +X toward its child).
fn rest_of(bones: &Bones, turn: Quat, convention: u32) -> Rig {
    let child_of = |i: usize| bones.iter().position(|b| b.1 == i as i32);
    let rest = (0..bones.len())
        .map(|i| {
            let toward = child_of(i)
                .map(|c| bones[c].2 - bones[i].2)
                .or_else(|| usize::try_from(bones[i].1).ok().map(|p| bones[i].2 - bones[p].2))
                .unwrap_or(Vec3::Y)
                .normalize();
            let toward = turn * toward;
            let roll = 0.3 + i as f32;
            let rotation = match convention {
                0 => turn,
                1 => Quat::from_axis_angle(toward, roll) * Quat::from_rotation_arc(Vec3::Y, toward),
                _ => Quat::from_axis_angle(toward, roll) * Quat::from_rotation_arc(Vec3::X, toward),
            };
            (rotation, turn * bones[i].2)
        })
        .collect();
    (bones.iter().map(|b| b.0.clone()).collect(), bones.iter().map(|b| b.1).collect(), rest)
}

/// Global positions with the fist's local rotations written over the rest pose.
fn posed(parents: &[i32], rest: &[(Quat, Vec3)], fist: &FistPose) -> Vec<Vec3> {
    let mut local: Vec<Quat> = (0..rest.len())
        .map(|b| match usize::try_from(parents[b]) {
            Ok(p) => rest[p].0.inverse() * rest[b].0,
            Err(_) => rest[b].0,
        })
        .collect();
    for (bone, q) in fist.bones() {
        local[bone] = q;
    }
    let mut rotation = vec![Quat::IDENTITY; rest.len()];
    let mut position = vec![Vec3::ZERO; rest.len()];
    for b in 0..rest.len() {
        match usize::try_from(parents[b]) {
            Ok(p) => {
                rotation[b] = rotation[p] * local[b];
                position[b] = position[p] + rotation[p] * (rest[p].0.inverse() * (rest[b].1 - rest[p].1));
            }
            Err(_) => {
                rotation[b] = local[b];
                position[b] = rest[b].1;
            }
        }
    }
    position
}

/// The bones without those `drop` says, parents renumbered (a dropped bone's children are dropped too).
fn without(bones: Bones, drop: impl Fn(&str) -> bool) -> Bones {
    let mut index = vec![-1i32; bones.len()];
    let mut kept = Bones::new();
    for (i, (name, parent, at)) in bones.into_iter().enumerate() {
        let parent = if parent < 0 { -1 } else { index[parent as usize] };
        if drop(&name) || (parent < 0 && !kept.is_empty()) {
            continue;
        }
        index[i] = kept.len() as i32;
        kept.push((name, parent, at));
    }
    kept
}

fn fist_of(bones: &Bones, turn: Quat, convention: u32) -> (Rig, FistPose) {
    let (names, parents, rest) = rest_of(bones, turn, convention);
    let map = map_bones(&names, &parents).expect("mapped");
    let fist = FistPose::new(&map, &names, &parents, &rest);
    ((names, parents, rest), fist)
}

fn bone(names: &[String], name: &str) -> usize {
    names.iter().position(|n| n == name).unwrap_or_else(|| panic!("no bone {name}"))
}

fn turns() -> [Quat; 3] {
    [Quat::IDENTITY, Quat::from_rotation_y(2.0), Quat::from_euler(glam::EulerRot::YXZ, -0.7, 0.4, 1.2)]
}

#[test]
fn the_palm_faces_down_in_a_t_pose_on_both_hands_whatever_the_bone_axes_and_the_rigs_turn() {
    for turn in turns() {
        for convention in 0..3 {
            let ((names, _, _), fist) = fist_of(&humanoid(0.0, false, "mixamo"), turn, convention);
            assert_eq!(fist.hands.len(), 2);
            for hand in &fist.hands {
                assert!(hand.palm.distance(turn * -Vec3::Y) < 1e-4, "{:?} palm {}", hand.side, hand.palm);
                let side = if hand.side == Side::Right { "Right" } else { "Left" };
                assert_eq!(hand.thumb, Some(bone(&names, &format!("{side}HandThumb1"))));
                assert_eq!(hand.fingers.len(), 4);
                assert_eq!(hand.curled.len(), 15, "five fingers of three bones");
            }
        }
    }
}

#[test]
fn the_fingertips_fold_under_the_palm_into_a_fist_the_same_for_every_bone_axis_convention() {
    let bones = humanoid(0.0, false, "mixamo");
    for turn in turns() {
        let mut first: Option<Vec<Vec3>> = None;
        for convention in 0..3 {
            let ((names, parents, rest), fist) = fist_of(&bones, turn, convention);
            let position = posed(&parents, &rest, &fist);
            for (side, palm) in [("Right", turn * -Vec3::Y), ("Left", turn * -Vec3::Y)] {
                let wrist = position[bone(&names, &format!("{side}Hand"))];
                for finger in ["Index", "Middle", "Ring", "Pinky"] {
                    let knuckle = position[bone(&names, &format!("{side}Hand{finger}1"))];
                    let last = position[bone(&names, &format!("{side}Hand{finger}3"))];
                    let open = rest[bone(&names, &format!("{side}Hand{finger}3"))].1;
                    assert!(knuckle.distance(rest[bone(&names, &format!("{side}Hand{finger}1"))].1) < 1e-5);
                    // The last bone's head: under the palm, back toward the wrist from the knuckles.
                    assert!((last - knuckle).dot(palm) > 0.035, "{side} {finger}: {}", (last - knuckle).dot(palm));
                    assert!(last.distance(wrist) < open.distance(wrist) - 0.03, "{side} {finger}");
                }
                // The thumb bends less, toward the palm too.
                let thumb = position[bone(&names, &format!("{side}HandThumb3"))];
                let thumb_open = rest[bone(&names, &format!("{side}HandThumb3"))].1;
                assert!((thumb - thumb_open).dot(palm) > 0.005, "{side} thumb");
            }
            match &first {
                None => first = Some(position),
                Some(first) => {
                    for (a, b) in first.iter().zip(&position) {
                        assert!(a.distance(*b) < 1e-4, "convention {convention}: {a} vs {b}");
                    }
                }
            }
        }
    }
}

#[test]
fn the_fist_is_the_same_whatever_the_rests_own_curl() {
    let ((names, parents, rest), fist) = fist_of(&humanoid(0.0, false, "mixamo"), Quat::IDENTITY, 1);
    let straight = posed(&parents, &rest, &fist);
    let ((_, parents, rest), fist) = fist_of(&humanoid(0.35, false, "mixamo"), Quat::IDENTITY, 1);
    let curled = posed(&parents, &rest, &fist);
    for finger in ["Index", "Middle", "Ring", "Pinky"] {
        let b1 = bone(&names, &format!("RightHand{finger}1"));
        let b3 = bone(&names, &format!("RightHand{finger}3"));
        // Same knuckle and bone lengths: the last joint lands at the same place.
        assert!((straight[b3] - straight[b1]).distance(curled[b3] - curled[b1]) < 1e-3, "{finger}");
    }
}

#[test]
fn metacarpals_keep_their_pose_and_makehumans_finger1_is_the_thumb() {
    let ((names, parents, rest), fist) = fist_of(&humanoid(0.1, true, "makehuman"), Quat::IDENTITY, 2);
    let right = &fist.hands[0];
    assert_eq!(right.side, Side::Right);
    assert_eq!(right.thumb, Some(bone(&names, "finger1-1.R")));
    let curled: Vec<usize> = right.curled.iter().map(|c| c.0).collect();
    assert!(!curled.contains(&bone(&names, "metacarpal1.R")));
    assert!(curled.contains(&bone(&names, "finger2-1.R")));
    assert_eq!(right.curled.len(), 15);
    assert!(right.palm.distance(-Vec3::Y) < 1e-4);
    let position = posed(&parents, &rest, &fist);
    assert!(position[bone(&names, "metacarpal2.R")].distance(rest[bone(&names, "metacarpal2.R")].1) < 1e-5);
    assert!((position[bone(&names, "finger3-3.R")] - position[bone(&names, "finger3-1.R")]).y < -0.035);
}

#[test]
fn without_names_the_thumb_is_the_finger_pointing_away_from_the_others() {
    let mut bones = humanoid(0.0, false, "mixamo");
    for (i, b) in bones.iter_mut().enumerate() {
        if b.0.contains("Hand") && b.0.len() > "RightHand".len() {
            b.0 = format!("Bone{i}");
        }
    }
    let ((names, _, _), fist) = fist_of(&bones, Quat::IDENTITY, 1);
    let thumb = bones.iter().position(|b| b.2 == Vec3::new(-0.75, 1.44, 0.03)).expect("thumb root");
    assert_eq!(fist.hands[0].thumb, Some(thumb), "{}", names[thumb]);
    assert!(fist.hands[0].palm.distance(-Vec3::Y) < 1e-4);
}

#[test]
fn weapon_and_ik_bones_below_the_hand_are_no_fingers_and_a_hand_without_fingers_curls_nothing() {
    let mut bones = humanoid(0.0, false, "mixamo");
    let hand = bones.iter().position(|b| b.0 == "RightHand").expect("hand") as i32;
    bones.push(("weapon_r".into(), hand, Vec3::new(-0.8, 1.4, 0.05)));
    bones.push(("ik_hand_gun".into(), hand, Vec3::new(-0.8, 1.4, 0.05)));
    let ((names, _, _), fist) = fist_of(&bones, Quat::IDENTITY, 1);
    let curled: Vec<usize> = fist.bones().map(|c| c.0).collect();
    assert!(!curled.contains(&bone(&names, "weapon_r")) && !curled.contains(&bone(&names, "ik_hand_gun")));
    assert_eq!(fist.len(), 30);

    let bare = without(humanoid(0.0, false, "mixamo"), |n| n.contains("Hand") && !n.ends_with("Hand"));
    let ((_, _, _), fist) = fist_of(&bare, Quat::IDENTITY, 1);
    assert!(fist.is_empty());
}

#[test]
fn a_single_finger_bone_without_a_thumb_bends_toward_the_palm_taken_as_down() {
    // The test rigs' hands (and CMU's fingers): one bone along the arm, no thumb.
    let bones = without(humanoid(0.0, false, "mixamo"), |n| {
        n.contains("Hand") && !n.ends_with("Hand") && !n.ends_with("Middle1")
    });
    let ((names, parents, rest), fist) = fist_of(&bones, Quat::IDENTITY, 2);
    let right = &fist.hands[0];
    assert_eq!((right.thumb, right.curled.len()), (None, 1));
    assert!(right.palm.distance(-Vec3::Y) < 1e-4);
    let finger = bone(&names, "RightHandMiddle1");
    let (_, q) = right.curled[0];
    let global = rest[parents[finger] as usize].0 * q;
    let open = (rest[finger].1 - rest[bone(&names, "RightHand")].1).normalize();
    let now = global * (rest[finger].0.inverse() * open);
    assert!((now.angle_between(open) - ONE_BONE_FLEXION_DEG.to_radians()).abs() < 1e-3, "{now}");
    assert!(now.y < -0.9);
}
