## Loads skinned characters (.glb) at run time, as a game can without the editor's importer
## (GLTFDocument.append_from_file + generate_scene), and prints one `CHARACTER <json>` line per file:
## its Skeleton3D (bone count, names, parents, the global rest positions of the punching body's bones), its
## MeshInstance3D's skin, the mesh's height, and a posing check done on the CPU with Godot's own skinning
## formula (bone global pose * the skin's bind pose, weighted): at rest the skinned mesh must equal the mesh,
## and with the right arm turned to point forward, the vertices bound to the hand must follow the hand.
## The bones' roles come from the file's `extras.punch_character.roles` (written by tests/fixtures/characters).
##   godot --headless --path godot_project --script tests/godot/load_character_glb.gd -- a.glb b.glb
## Run by tests/python/test_characters.py. Exits 1 when a file does not load as a skinned character.
extends SceneTree


func _initialize() -> void:
	_run.call_deferred()  # once the root is inside the tree, so that loaded scenes are too


func _run() -> void:
	var failed := false
	for path in OS.get_cmdline_user_args():
		var report := _inspect(path)
		failed = failed or report.has("error")
		print("CHARACTER ", JSON.stringify(report))
	quit(1 if failed else 0)


func _inspect(path: String) -> Dictionary:
	var document := GLTFDocument.new()
	var state := GLTFState.new()
	var error := document.append_from_file(path, state)
	if error != OK:
		return {"path": path, "error": "append_from_file: %s" % error_string(error)}
	var scene := document.generate_scene(state)
	if scene == null:
		return {"path": path, "error": "generate_scene returned null"}
	root.add_child(scene)
	var report := _report(path, scene, state)
	scene.free()
	return report


func _report(path: String, scene: Node, state: GLTFState) -> Dictionary:
	var skeletons := scene.find_children("*", "Skeleton3D", true, false)
	var meshes := scene.find_children("*", "MeshInstance3D", true, false)
	if skeletons.size() != 1 or meshes.size() != 1:
		return {"path": path, "error": "%d skeletons and %d meshes (want one of each)" % [skeletons.size(), meshes.size()]}
	var skeleton: Skeleton3D = skeletons[0]
	var mesh_instance: MeshInstance3D = meshes[0]
	var names := []
	var parents := []
	for bone in skeleton.get_bone_count():
		names.append(skeleton.get_bone_name(bone))
		parents.append(skeleton.get_bone_parent(bone))
	var roles: Dictionary = state.json.get("extras", {}).get("punch_character", {}).get("roles", {})
	var role_bones := {}
	var rest_positions := {}
	var rest_axes := {}
	for role in roles:
		var bone := _find_bone(skeleton, roles[role])
		role_bones[role] = bone
		if bone >= 0:
			var rest := skeleton.global_transform * skeleton.get_bone_global_rest(bone)
			rest_positions[role] = [rest.origin.x, rest.origin.y, rest.origin.z]
			rest_axes[role] = [rest.basis.x.x, rest.basis.x.y, rest.basis.x.z, rest.basis.y.x, rest.basis.y.y, rest.basis.y.z,
					rest.basis.z.x, rest.basis.z.y, rest.basis.z.z]
	var report := {
		"path": path, "skeleton_name": String(skeleton.name), "bone_count": skeleton.get_bone_count(), "bone_names": names,
		"bone_parents": parents, "roles_found": role_bones, "rest_m": rest_positions, "rest_axes": rest_axes,
		"has_skin": mesh_instance.skin != null, "skin_binds": mesh_instance.skin.get_bind_count() if mesh_instance.skin else 0,
		"mesh_skeleton_is_skeleton": mesh_instance.get_node_or_null(mesh_instance.skeleton) == skeleton,
	}
	var arrays := mesh_instance.mesh.surface_get_arrays(0)
	var vertices: PackedVector3Array = arrays[Mesh.ARRAY_VERTEX]
	var to_scene := mesh_instance.global_transform
	var rest_box := _box(vertices, to_scene)
	report["vertex_count"] = vertices.size()
	report["height_m"] = rest_box.size.y
	report["rest_aabb"] = _box_list(rest_box)
	if mesh_instance.skin == null or not role_bones.has("upper_arm_r") or role_bones["upper_arm_r"] < 0 or role_bones["hand_r"] < 0:
		report["error"] = "no skin, or no right upper arm or hand bone to pose"
		return report
	_pose_check(report, skeleton, mesh_instance, arrays, role_bones["upper_arm_r"], role_bones["hand_r"])
	return report


## Godot keeps glTF names except characters a node name cannot hold (`mixamorig:Hips` becomes `mixamorig_Hips`).
func _find_bone(skeleton: Skeleton3D, name: String) -> int:
	var bone := skeleton.find_bone(name)
	return bone if bone >= 0 else skeleton.find_bone(name.validate_node_name())


func _pose_check(report: Dictionary, skeleton: Skeleton3D, mesh_instance: MeshInstance3D, arrays: Array, upper: int, hand: int) -> void:
	var skin := mesh_instance.skin
	var vertices: PackedVector3Array = arrays[Mesh.ARRAY_VERTEX]
	var bones: PackedInt32Array = arrays[Mesh.ARRAY_BONES]
	var weights: PackedFloat32Array = arrays[Mesh.ARRAY_WEIGHTS]
	var per_vertex := bones.size() / vertices.size()
	var bind_bones := []
	for bind in skin.get_bind_count():
		var bone := skin.get_bind_bone(bind)
		bind_bones.append(bone if bone >= 0 else skeleton.find_bone(skin.get_bind_name(bind)))
	report["influences_per_vertex"] = per_vertex
	# At rest, skinning must give back the mesh: the bind poses are the inverses of the bones' rest.
	var rest := _skin(skeleton, skin, bind_bones, vertices, bones, weights, per_vertex)
	var rest_error := 0.0
	for i in vertices.size():
		rest_error = maxf(rest_error, rest[i].distance_to(vertices[i]))
	report["rest_skinning_error_m"] = rest_error
	# Turn the right arm about the shoulder so that shoulder -> wrist points forward (+Z), like a jab.
	var shoulder := skeleton.get_bone_global_pose(upper).origin
	var hand_rest := skeleton.get_bone_global_pose(hand)
	var arm := (hand_rest.origin - shoulder).normalized()
	var turn := Basis(arm.cross(Vector3.BACK).normalized(), arm.angle_to(Vector3.BACK))
	var parent_global := skeleton.get_bone_global_pose(skeleton.get_bone_parent(upper))
	var upper_global := skeleton.get_bone_global_pose(upper)
	var wanted := Transform3D(turn * upper_global.basis, upper_global.origin)
	var local := parent_global.affine_inverse() * wanted
	skeleton.set_bone_pose_rotation(upper, local.basis.get_rotation_quaternion())
	var hand_posed := skeleton.get_bone_global_pose(hand)
	var expected := shoulder + Vector3.BACK * shoulder.distance_to(hand_rest.origin)
	report["posed_hand_error_m"] = hand_posed.origin.distance_to(expected)
	var posed := _skin(skeleton, skin, bind_bones, vertices, bones, weights, per_vertex)
	# The whole arm turned as one: vertices bound only to the upper arm and the bones below it keep their
	# place in the hand's frame; the others (the body, the armpit's blend) are checked by the AABB.
	var in_arm := {}
	for bone in skeleton.get_bone_count():
		var ancestor := bone
		while ancestor >= 0 and ancestor != upper:
			ancestor = skeleton.get_bone_parent(ancestor)
		in_arm[bone] = ancestor == upper
	var arm_vertices := 0
	var arm_error := 0.0
	for i in vertices.size():
		var only_arm := true
		for k in per_vertex:
			if weights[i * per_vertex + k] > 0.0 and not in_arm[bind_bones[bones[i * per_vertex + k]]]:
				only_arm = false
		if only_arm:
			arm_vertices += 1
			arm_error = maxf(arm_error, (hand_posed.affine_inverse() * posed[i]).distance_to(hand_rest.affine_inverse() * vertices[i]))
	report["arm_vertices"] = arm_vertices
	report["arm_vertex_error_m"] = arm_error
	report["posed_aabb"] = _box_list(_box(posed, mesh_instance.global_transform))
	skeleton.reset_bone_poses()


## Godot's linear blend skinning on the CPU: sum of weight * bone global pose * bind pose * vertex.
func _skin(skeleton: Skeleton3D, skin: Skin, bind_bones: Array, vertices: PackedVector3Array, bones: PackedInt32Array,
		weights: PackedFloat32Array, per_vertex: int) -> PackedVector3Array:
	var matrices: Array[Transform3D] = []
	for bind in skin.get_bind_count():
		matrices.append(skeleton.get_bone_global_pose(bind_bones[bind]) * skin.get_bind_pose(bind))
	var out := PackedVector3Array()
	out.resize(vertices.size())
	for i in vertices.size():
		var sum := Vector3.ZERO
		for k in per_vertex:
			var w := weights[i * per_vertex + k]
			if w > 0.0:
				sum += w * (matrices[bones[i * per_vertex + k]] * vertices[i])
		out[i] = sum
	return out


func _box(points: PackedVector3Array, to_scene: Transform3D) -> AABB:
	var box := AABB(to_scene * points[0], Vector3.ZERO)
	for point in points:
		box = box.expand(to_scene * point)
	return box


func _box_list(box: AABB) -> Array:
	return [box.position.x, box.position.y, box.position.z, box.end.x, box.end.y, box.end.z]
