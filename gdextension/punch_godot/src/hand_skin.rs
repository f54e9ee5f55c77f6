//! Reads where a rig's hands are from its skin: the rest positions of the vertices bound mostly to each hand and
//! the bones below it, for `punch_core::rig::skeleton_pose::rig_fists` (the bones alone cannot say where the middle of
//! some hands is).

use glam::Vec3;
use godot::builtin::{PackedFloat32Array, PackedInt32Array, PackedVector3Array, Transform3D, VarArray};
use godot::classes::mesh::ArrayType;
use godot::classes::{MeshInstance3D, Node, Skeleton3D};
use godot::obj::{EngineEnum, Gd};

use crate::convert::vec3;

/// The rest positions (skeleton space) of the skin over each of `hands` ([right, left] bone indices): the vertices
/// of every skinned mesh that this skeleton deforms (found under the skeleton's parent) whose weights lie at least
/// half on the hand and the bones below it. Empty for a hand (or a rig) without skin.
pub fn hand_skin_points(skeleton: &Gd<Skeleton3D>, hands: [usize; 2], parents: &[i32]) -> [Vec<Vec3>; 2] {
    let mut points = [Vec::new(), Vec::new()];
    let below = |bone: i32, hand: usize| -> bool {
        let mut at = bone;
        for _ in 0..=parents.len() {
            match usize::try_from(at) {
                Ok(b) if b == hand => return true,
                Ok(b) if b < parents.len() => at = parents[b],
                _ => return false,
            }
        }
        false
    };
    let search_from: Gd<Node> = skeleton.get_parent().unwrap_or_else(|| skeleton.clone().upcast());
    for node in
        search_from.find_children_ex("*").type_("MeshInstance3D").recursive(true).owned(false).done().iter_shared()
    {
        let Ok(mesh_instance) = node.try_cast::<MeshInstance3D>() else { continue };
        let (Some(skin), Some(mesh)) = (mesh_instance.get_skin(), mesh_instance.get_mesh()) else { continue };
        let deforms_this = mesh_instance
            .get_node_or_null(&mesh_instance.get_skeleton_path())
            .is_some_and(|n| n.instance_id() == skeleton.instance_id());
        if !deforms_this {
            continue;
        }
        // Per bind: its rest matrix (bone's global rest times bind pose) and which hand it belongs to.
        let binds: Vec<(Transform3D, [bool; 2])> = (0..skin.get_bind_count())
            .map(|bind| {
                let mut bone = skin.get_bind_bone(bind);
                if bone < 0 {
                    bone = skeleton.find_bone(&skin.get_bind_name(bind).to_string());
                }
                if bone < 0 || bone >= skeleton.get_bone_count() {
                    return (Transform3D::IDENTITY, [false, false]);
                }
                let matrix = skeleton.get_bone_global_rest(bone) * skin.get_bind_pose(bind);
                (matrix, hands.map(|hand| below(bone, hand)))
            })
            .collect();
        for surface in 0..mesh.get_surface_count() {
            let arrays = mesh.surface_get_arrays(surface);
            let (Some(vertices), Some(bones), Some(weights)) = (
                array::<PackedVector3Array>(&arrays, ArrayType::VERTEX),
                array::<PackedInt32Array>(&arrays, ArrayType::BONES),
                array::<PackedFloat32Array>(&arrays, ArrayType::WEIGHTS),
            ) else {
                continue;
            };
            let (vertices, bones, weights) = (vertices.as_slice(), bones.as_slice(), weights.as_slice());
            if vertices.is_empty() || bones.len() != weights.len() || bones.len() % vertices.len() != 0 {
                continue;
            }
            let per_vertex = bones.len() / vertices.len();
            for (i, vertex) in vertices.iter().enumerate() {
                let influences = (i * per_vertex..(i + 1) * per_vertex)
                    .filter_map(|k| binds.get(usize::try_from(bones[k]).ok()?).map(|bind| (bind, weights[k])));
                let mut share = [0.0f32; 2];
                let mut position = Vec3::ZERO;
                for ((matrix, in_hand), weight) in influences {
                    position += weight * vec3(*matrix * *vertex);
                    for side in 0..2 {
                        share[side] += if in_hand[side] { weight } else { 0.0 };
                    }
                }
                for side in 0..2 {
                    if share[side] >= 0.5 {
                        points[side].push(position);
                    }
                }
            }
        }
    }
    points
}

fn array<T: godot::meta::FromGodot>(arrays: &VarArray, kind: ArrayType) -> Option<T> {
    arrays.get(kind.ord() as usize).and_then(|v| v.try_to::<T>().ok())
}
