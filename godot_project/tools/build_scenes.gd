## Builds the addon's character and sandbag scenes from the anthropometry below and saves them as
## res://addons/punch_controller/scenes/punch_character.tscn and punch_sandbag.tscn.
## Run: tools/godot --headless --path godot_project --script res://tools/build_scenes.gd
##
## Body data: de Leva (1996) segment parameters scaled to an 80 kg, 1.74 m male. Welded segments become one
## rigid body (upper trunk + middle trunk = torso; forearm + hand = forearm), whose centre of mass and principal
## moments come from the parallel-axis theorem; the head (with the neck) hangs on a sprung neck joint. Arm length convention: shoulder joint to
## fist centre = 0.282 + 0.269 + 0.068 = 0.619 m (the paper's 0.84 m arm measures to the fingertips of a
## longer reference person). Frame: the character faces +Z, +X is its left, +Y up; the pose is a guard.
##
## Every body has exactly one collision shape. When a body touches another with two shapes at once, Jolt
## orders the two contact manifolds by body ids, so the same punch would come out differently (in the last
## bits) depending on where the character sits in the physics world; one shape per body keeps the training
## server's characters bitwise identical whatever their slot.
extends SceneTree

const SCENE_DIR := "res://addons/punch_controller/scenes/"

# Heights above the floor (m): hip joint centres, omphalion (waist joint), shoulder joint centres.
const WAIST_Y := 1.056
const SHOULDER_Y := 1.42
const SHOULDER_HALF_WIDTH := 0.18
# Segment lengths (m): shoulder-elbow, elbow-wrist; fist centre 0.068 beyond the wrist.
const UPPER_ARM_LENGTH := 0.282
const FOREARM_LENGTH := 0.269
const FIST_FROM_WRIST := 0.068
# Guard pose: upper arm 35 degrees forward of vertical, elbow bent 120 degrees.
const UPPER_ARM_FORWARD_DEG := 35.0
const ELBOW_FLEXION_DEG := 120.0

# The torso and the head together are the welded trunk the policies were trained on (31.38 kg, centre of mass
# 1.3313 m, principal moments 0.8672, 0.3167, 1.0310 kg m²): the head's segment (6.94% of the mass, 0.2429 m
# from the suprasternale's height 1.442 m to the vertex, centre of mass halfway, radii of gyration 31.5%, 26.1%
# and 30.3% of its length) taken out by the parallel-axis theorem.
const TORSO := {"mass": 25.832, "com_y": 1.2815, "inertia": Vector3(0.4711, 0.2944, 0.6373)}
const HEAD := {"mass": 5.552, "com_y": 1.5636, "inertia": Vector3(0.0325, 0.0223, 0.0301)}
# The neck joint's height, and the head's one collision shape: a capsule from the neck to the crown.
const NECK_Y := 1.442  # the head's segment starts at the suprasternale's height
const HEAD_CAPSULE := {"radius": 0.09, "height": 0.26, "centre_y": 1.58}
const UPPER_ARM := {"mass": 2.17, "com_from_shoulder": 0.163, "inertia": Vector3(0.01249, 0.00431, 0.01402)}
const FOREARM := {"mass": 1.79, "com_from_elbow": 0.1816, "inertia": Vector3(0.02386, 0.00196, 0.02489)}
const FIST_RADIUS := 0.045

const BAG := {"mass": 35.0, "radius": 0.175, "height": 1.0, "rope_above_top": 0.5}

var _skin := _material(Color(0.87, 0.68, 0.55))
var _shirt := _material(Color(0.18, 0.32, 0.55))
var _glove := _material(Color(0.75, 0.08, 0.08))


func _initialize() -> void:
	var ok := _save(_build_character(), "punch_character.tscn") and _save(_build_sandbag(), "punch_sandbag.tscn")
	quit(0 if ok else 1)


func _material(color: Color) -> StandardMaterial3D:
	var material := StandardMaterial3D.new()
	material.albedo_color = color
	material.roughness = 0.8
	return material


func _save(root: Node, file_name: String) -> bool:
	if root == null:
		printerr("could not build %s" % file_name)
		return false
	var packed := PackedScene.new()
	var error := packed.pack(root)
	if error == OK:
		error = ResourceSaver.save(packed, SCENE_DIR + file_name)
	root.free()
	if error != OK:
		printerr("could not save %s: %s" % [file_name, error_string(error)])
		return false
	print("saved ", SCENE_DIR + file_name)
	return true


## Makes `owner` the owner of every descendant of `node`, so that packing saves them.
func _own(node: Node, owner: Node) -> void:
	for child in node.get_children():
		child.owner = owner
		_own(child, owner)


func _shape(parent: Node3D, name: String, shape: Shape3D, mesh: Mesh, material: Material, at: Transform3D) -> CollisionShape3D:
	var collision := CollisionShape3D.new()
	collision.name = name
	collision.shape = shape
	collision.transform = at
	parent.add_child(collision)
	var visual := MeshInstance3D.new()
	visual.name = name + "Mesh"
	visual.mesh = mesh
	visual.material_override = material
	visual.transform = at
	parent.add_child(visual)
	return collision


func _box(size: Vector3) -> Array:
	var shape := BoxShape3D.new()
	shape.size = size
	var mesh := BoxMesh.new()
	mesh.size = size
	return [shape, mesh]


func _capsule(radius: float, height: float) -> Array:
	var shape := CapsuleShape3D.new()
	shape.radius = radius
	shape.height = height
	var mesh := CapsuleMesh.new()
	mesh.radius = radius
	mesh.height = height
	return [shape, mesh]


func _sphere(radius: float) -> Array:
	var shape := SphereShape3D.new()
	shape.radius = radius
	var mesh := SphereMesh.new()
	mesh.radius = radius
	mesh.height = 2.0 * radius
	return [shape, mesh]


## One convex hull around the forearm (a 4 cm radius tube from elbow to wrist) and the fist (a sphere).
func _forearm_hull(elbow_y: float, wrist_y: float, fist_centre: Vector3) -> ConvexPolygonShape3D:
	var points := PackedVector3Array()
	for i in 8:
		var angle := TAU * i / 8.0
		var ring := Vector3(cos(angle), 0, sin(angle)) * 0.04
		points.append(ring + Vector3(0, elbow_y, 0))
		points.append(ring + Vector3(0, wrist_y, 0))
	for i in 12:
		# Points of an icosahedron on the fist's sphere.
		var golden := (1.0 + sqrt(5.0)) / 2.0
		var corners := [Vector3(-1, golden, 0), Vector3(1, golden, 0), Vector3(-1, -golden, 0), Vector3(1, -golden, 0),
			Vector3(0, -1, golden), Vector3(0, 1, golden), Vector3(0, -1, -golden), Vector3(0, 1, -golden),
			Vector3(golden, 0, -1), Vector3(golden, 0, 1), Vector3(-golden, 0, -1), Vector3(-golden, 0, 1)]
		points.append(fist_centre + corners[i].normalized() * FIST_RADIUS)
	var hull := ConvexPolygonShape3D.new()
	hull.points = points
	return hull


func _rigid_body(name: String, mass: float, inertia: Vector3, at: Transform3D) -> RigidBody3D:
	var body := RigidBody3D.new()
	body.name = name
	body.mass = mass
	body.inertia = inertia
	body.center_of_mass_mode = RigidBody3D.CENTER_OF_MASS_MODE_CUSTOM
	body.center_of_mass = Vector3.ZERO  # every body's origin is its centre of mass
	body.can_sleep = false
	body.transform = at
	# Layer 2: the character; it collides with Godot's default layer 1, with other characters and with the
	# bag (layer 3).
	# Under Jolt, a body that does not mask the other acts as immovable to it: the bag masks layer 2 too.
	body.collision_layer = 2
	body.collision_mask = 1 | 2 | 4
	return body


func _joint(name: String, at: Vector3, parent: Node3D, child: Node3D, root: Node3D) -> void:
	var joint := Generic6DOFJoint3D.new()
	joint.name = name
	joint.position = at  # identity basis: joint frames are aligned with the character frame at rest
	root.add_child(joint)
	joint.node_a = joint.get_path_to(parent)
	joint.node_b = joint.get_path_to(child)


func _build_character() -> Node3D:
	var root: Node3D = ClassDB.instantiate("PunchCharacter")
	root.name = "PunchCharacter"

	# Kinematic: PunchCharacter carries it, from code in the physics step, to wherever the character's root moves
	# (not an AnimationPlayer, which makes Jolt's joints on it oscillate: godotengine/godot#115051); the trunk and
	# arms follow it through their joints. sync_to_physics off: the node holds the code's target.
	var pelvis := AnimatableBody3D.new()
	pelvis.sync_to_physics = false
	pelvis.name = "Pelvis"
	pelvis.position = Vector3(0, 0.98, 0)
	pelvis.collision_layer = 2
	pelvis.collision_mask = 1 | 2 | 4
	root.add_child(pelvis)
	var pelvis_box := _box(Vector3(0.32, 0.15, 0.2))
	_shape(pelvis, "PelvisShape", pelvis_box[0], pelvis_box[1], _shirt, Transform3D.IDENTITY)

	var torso := _rigid_body("Torso", TORSO.mass, TORSO.inertia, Transform3D(Basis.IDENTITY, Vector3(0, TORSO.com_y, 0)))
	root.add_child(torso)
	# One box from the waist (omphalion) to the shoulders (suprasternale).
	var trunk := _box(Vector3(0.34, 0.386, 0.22))
	_shape(torso, "TorsoShape", trunk[0], trunk[1], _shirt, Transform3D(Basis.IDENTITY, Vector3(0, 1.249 - TORSO.com_y, 0)))
	_joint("Waist", Vector3(0, WAIST_Y, 0), pelvis, torso, root)

	var upper_angle := deg_to_rad(UPPER_ARM_FORWARD_DEG)
	var forearm_angle := deg_to_rad(UPPER_ARM_FORWARD_DEG + ELBOW_FLEXION_DEG)
	var upper_direction := Vector3(0, -cos(upper_angle), sin(upper_angle))
	var forearm_direction := Vector3(0, -cos(forearm_angle), sin(forearm_angle))
	for side in [["R", -1.0], ["L", 1.0]]:
		var suffix: String = side[0]
		var shoulder := Vector3(side[1] * SHOULDER_HALF_WIDTH, SHOULDER_Y, 0)
		var elbow := shoulder + UPPER_ARM_LENGTH * upper_direction
		# Each arm body's local +Y points along the bone toward its proximal joint.
		var upper_basis := Basis(Vector3.RIGHT, -upper_angle)
		var upper := _rigid_body("UpperArm" + suffix, UPPER_ARM.mass, UPPER_ARM.inertia,
			Transform3D(upper_basis, shoulder + UPPER_ARM.com_from_shoulder * upper_direction))
		root.add_child(upper)
		var upper_capsule := _capsule(0.045, UPPER_ARM_LENGTH + 0.02)
		_shape(upper, "UpperArmShape", upper_capsule[0], upper_capsule[1], _skin,
			Transform3D(Basis.IDENTITY, Vector3(0, UPPER_ARM.com_from_shoulder - UPPER_ARM_LENGTH / 2.0, 0)))
		_joint("Shoulder" + suffix, shoulder, torso, upper, root)

		var forearm_basis := Basis(Vector3.RIGHT, -forearm_angle)
		var forearm := _rigid_body("Forearm" + suffix, FOREARM.mass, FOREARM.inertia,
			Transform3D(forearm_basis, elbow + FOREARM.com_from_elbow * forearm_direction))
		root.add_child(forearm)
		var fist_offset := Vector3(0, FOREARM.com_from_elbow - (FOREARM_LENGTH + FIST_FROM_WRIST), 0)
		var forearm_shape := CollisionShape3D.new()
		forearm_shape.name = "ForearmShape"
		forearm_shape.shape = _forearm_hull(FOREARM.com_from_elbow, FOREARM.com_from_elbow - FOREARM_LENGTH, fist_offset)
		forearm.add_child(forearm_shape)
		var forearm_mesh := MeshInstance3D.new()
		forearm_mesh.name = "ForearmMesh"
		forearm_mesh.mesh = _capsule(0.04, FOREARM_LENGTH)[1]
		forearm_mesh.material_override = _skin
		forearm_mesh.position = Vector3(0, FOREARM.com_from_elbow - FOREARM_LENGTH / 2.0, 0)
		forearm.add_child(forearm_mesh)
		var fist_mesh := MeshInstance3D.new()
		fist_mesh.name = "FistMesh"
		fist_mesh.mesh = _sphere(FIST_RADIUS)[1]
		fist_mesh.material_override = _glove
		fist_mesh.position = fist_offset
		forearm.add_child(fist_mesh)
		var marker := Marker3D.new()
		marker.name = "Fist" + suffix
		marker.position = fist_offset
		marker.set_meta("radius_m", FIST_RADIUS)  # the fist's size, for sensing which contacts are the fist's
		forearm.add_child(marker)
		_joint("Elbow" + suffix, elbow, upper, forearm, root)

	# The head last (Body::ALL order), on the neck: a spring, no motor (the Rust core's NECK).
	var head := _rigid_body("Head", HEAD.mass, HEAD.inertia, Transform3D(Basis.IDENTITY, Vector3(0, HEAD.com_y, 0)))
	root.add_child(head)
	var head_shape := CollisionShape3D.new()
	head_shape.name = "HeadShape"
	head_shape.shape = _capsule(HEAD_CAPSULE.radius, HEAD_CAPSULE.height)[0]
	head_shape.position = Vector3(0, HEAD_CAPSULE.centre_y - HEAD.com_y, 0)
	head.add_child(head_shape)
	var head_mesh := MeshInstance3D.new()
	head_mesh.name = "HeadMesh"
	head_mesh.mesh = _sphere(0.1)[1]
	head_mesh.material_override = _skin
	head_mesh.position = Vector3(0, 1.58 - HEAD.com_y, 0)
	head.add_child(head_mesh)
	var neck_mesh := MeshInstance3D.new()
	neck_mesh.name = "NeckMesh"
	neck_mesh.mesh = _capsule(0.05, 0.14)[1]
	neck_mesh.material_override = _skin
	neck_mesh.position = Vector3(0, 1.49 - HEAD.com_y, 0)
	head.add_child(neck_mesh)
	_joint("Neck", Vector3(0, NECK_Y, 0), torso, head, root)

	# Limits and motors from the Rust core's DOF table, stored in the scene (PunchCharacter explains why).
	if not root.call("store_joint_settings"):
		return null
	_own(root, root)
	return root


func _build_sandbag() -> Node3D:
	# The root's origin is the bag's centre of mass: placing the root places the bag.
	var root := Node3D.new()
	root.name = "PunchSandbag"
	var bag := RigidBody3D.new()
	bag.name = "Bag"
	bag.mass = BAG.mass
	bag.can_sleep = false
	bag.max_contacts_reported = 8  # the trainer reads each fist's contact impulse on the bag
	bag.collision_layer = 4
	bag.collision_mask = 2 | 4  # the character's bodies (and other bags)
	root.add_child(bag)
	var cylinder := CylinderShape3D.new()
	cylinder.radius = BAG.radius
	cylinder.height = BAG.height
	var mesh := CylinderMesh.new()
	mesh.top_radius = BAG.radius
	mesh.bottom_radius = BAG.radius
	mesh.height = BAG.height
	_shape(bag, "BagShape", cylinder, mesh, _material(Color(0.55, 0.12, 0.1)), Transform3D.IDENTITY)
	var rope_length: float = BAG.rope_above_top
	var rope_mesh := CylinderMesh.new()
	rope_mesh.top_radius = 0.01
	rope_mesh.bottom_radius = 0.01
	rope_mesh.height = rope_length
	var rope := MeshInstance3D.new()
	rope.name = "RopeMesh"
	rope.mesh = rope_mesh
	rope.material_override = _material(Color(0.2, 0.2, 0.2))
	rope.position = Vector3(0, BAG.height / 2.0 + rope_length / 2.0, 0)
	bag.add_child(rope)
	# The rope is modelled as a rigid link: a pin joint fixed to the world above the bag.
	var hook := PinJoint3D.new()
	hook.name = "Hook"
	hook.position = Vector3(0, BAG.height / 2.0 + rope_length, 0)
	root.add_child(hook)
	hook.node_b = hook.get_path_to(bag)
	_own(root, root)
	return root
