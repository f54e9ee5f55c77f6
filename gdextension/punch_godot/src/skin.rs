//! Reads where a rig's hands and head are from its skin: the rest positions of the vertices bound mostly to a bone
//! and the bones below it, for `punch_core::rig::skeleton_pose::rig_fists` (the bones alone cannot say where the
//! middle of some hands is) and `rig_shoulder_to_crown` (nor where the crown is).

use glam::Vec3;
use godot::builtin::{PackedFloat32Array, PackedInt32Array, PackedVector3Array, Transform3D, VarArray};
use godot::classes::mesh::ArrayType;
use godot::classes::{MeshInstance3D, Node, Skeleton3D};
use godot::obj::{EngineEnum, Gd};

use crate::convert::vec3;

/// The rest positions (skeleton space) of the skin over each of `parts` (bone indices, as [right hand, left hand,
/// head]): the vertices of every skinned mesh that this skeleton deforms (found under the skeleton's parent) whose
/// weights lie at least half on the bone and the bones below it. Empty for a part (or a rig) without skin.
pub fn skin_points<const N: usize>(skeleton: &Gd<Skeleton3D>, parts: [usize; N], parents: &[i32]) -> [Vec<Vec3>; N] {
    let mut points = std::array::from_fn(|_| Vec::new());
    let below = |bone: i32, part: usize| -> bool {
        let mut at = bone;
        for _ in 0..=parents.len() {
            match usize::try_from(at) {
                Ok(b) if b == part => return true,
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
        // Per bind: its rest matrix (bone's global rest times bind pose) and which parts it belongs to.
        let binds: Vec<(Transform3D, [bool; N])> = (0..skin.get_bind_count())
            .map(|bind| {
                let mut bone = skin.get_bind_bone(bind);
                if bone < 0 {
                    bone = skeleton.find_bone(&skin.get_bind_name(bind).to_string());
                }
                if bone < 0 || bone >= skeleton.get_bone_count() {
                    return (Transform3D::IDENTITY, [false; N]);
                }
                let matrix = skeleton.get_bone_global_rest(bone) * skin.get_bind_pose(bind);
                (matrix, parts.map(|part| below(bone, part)))
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
                let mut share = [0.0f32; N];
                let mut position = Vec3::ZERO;
                for ((matrix, in_part), weight) in influences {
                    position += weight * vec3(*matrix * *vertex);
                    for (part_share, inside) in share.iter_mut().zip(in_part) {
                        *part_share += if *inside { weight } else { 0.0 };
                    }
                }
                for (part_points, part_share) in points.iter_mut().zip(share) {
                    if part_share >= 0.5 {
                        part_points.push(position);
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
