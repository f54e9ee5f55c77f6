## Every kind of target: one character per kind, each punching (straight demo policy, sigma 0) a target at
## the spec's offset in front of it: the addon's sandbag, a floating RigidBody3D box on Godot's default layer,
## a CharacterBody3D enemy, a StaticBody3D post, an Area3D hurtbox, a Marker3D on a box (the box is hit), a
## bone attachment carrying a hurtbox on an enemy's skeleton, a plain Node3D with nothing there, and a plain
## Node3D with a box there (a bystander: hit with the default `hit_layers`, not with layer 2 only). Prints
## `TARGETS_SCENE <json>`: per kind the `hit` signals (impulse, what was hit, push) and `punch_finished`.
extends SceneTree

const POLICY := "res://addons/punch_controller/policies/straight.onnx"
const KINDS := ["sandbag", "rigid_box", "character_body", "static_post", "area", "marker_on_box", "bone_attachment", "empty",
	"bystander", "bystander_off_hit_layers"]
var _report := {}
var _controllers: Array[Node] = []
var _frames := 0


func _initialize() -> void:
	for index in KINDS.size():
		var kind: String = KINDS[index]
		var character: Node3D = load("res://addons/punch_controller/scenes/punch_character.tscn").instantiate()
		character.position = Vector3(4.0 * index, 0, 0)
		root.add_child(character)
		var spot := Node3D.new()
		spot.position = character.transform * PunchSpec.default_target_offset()
		root.add_child(spot)
		var target := _make_target(kind, spot)
		var controller: Node = ClassDB.instantiate("PunchController")
		controller.set("character", character)
		controller.set("target", target)
		controller.set("policy", load(POLICY))
		if kind == "bystander_off_hit_layers":
			controller.set("hit_layers", 1 << 1)
		root.add_child(controller)
		_report[kind] = {"hits": [], "finished": null}
		controller.connect("hit", func(impulse, speed, _position, body, push, _hand, _part, _blocked):
			_report[kind].hits.append({"impulse": impulse, "speed": speed, "body": body.name if body else "",
				"push": [push.x, push.y, push.z]}))
		controller.connect("punch_finished", func(metrics): _report[kind].finished = metrics)
		_controllers.append(controller)


## A target of `kind` at `spot` (its centre where the policy aims).
func _make_target(kind: String, spot: Node3D) -> Node3D:
	match kind:
		"sandbag":
			var sandbag: Node3D = load("res://addons/punch_controller/scenes/punch_sandbag.tscn").instantiate()
			spot.add_child(sandbag)
			return sandbag.get_node("Bag")
		"rigid_box", "marker_on_box", "bystander", "bystander_off_hit_layers":
			var box := RigidBody3D.new()  # Godot's default layer and mask (1)
			box.name = "Box"
			box.gravity_scale = 0.0
			box.mass = 20.0
			box.add_child(_shape(_box_shape()))
			spot.add_child(box)
			if kind == "rigid_box":
				return box
			if kind.begins_with("bystander"):
				var aim := Node3D.new()  # a separate node at the same place: the box is not the target's
				aim.position = spot.position
				root.add_child(aim)
				return aim
			var marker := Marker3D.new()
			box.add_child(marker)
			return marker
		"character_body":
			var enemy := CharacterBody3D.new()
			enemy.name = "Enemy"
			enemy.add_child(_shape(_capsule()))
			spot.add_child(enemy)
			return enemy
		"static_post":
			var post := StaticBody3D.new()
			post.name = "Post"
			var cylinder := CylinderShape3D.new()
			cylinder.radius = 0.175
			post.add_child(_shape(cylinder))
			spot.add_child(post)
			return post
		"area":
			return _hurtbox(spot)
		"bone_attachment":
			var enemy := CharacterBody3D.new()
			enemy.collision_layer = 0  # only its hurtbox can be hit
			spot.add_child(enemy)
			var skeleton := Skeleton3D.new()
			enemy.add_child(skeleton)
			skeleton.add_bone("head")
			var attachment := BoneAttachment3D.new()
			skeleton.add_child(attachment)
			attachment.bone_name = "head"
			_hurtbox(attachment)
			return attachment
	return spot  # "empty": a plain Node3D with nothing to hit


func _hurtbox(parent: Node3D) -> Area3D:
	var area := Area3D.new()
	area.name = "Hurtbox"
	var sphere := SphereShape3D.new()
	sphere.radius = 0.2
	area.add_child(_shape(sphere))
	parent.add_child(area)
	return area


func _shape(shape: Shape3D) -> CollisionShape3D:
	var node := CollisionShape3D.new()
	node.shape = shape
	return node


func _box_shape() -> BoxShape3D:
	var box := BoxShape3D.new()
	box.size = Vector3(0.35, 0.6, 0.35)
	return box


func _capsule() -> CapsuleShape3D:
	var capsule := CapsuleShape3D.new()
	capsule.radius = 0.2
	capsule.height = 1.0
	return capsule


func _physics_process(_delta: float) -> bool:
	_frames += 1
	if _frames == 2:
		for controller in _controllers:
			controller.call("punch")
	var done := _report.values().all(func(entry): return entry.finished != null)
	if done or _frames > 300:
		print("TARGETS_SCENE ", JSON.stringify(_report))
		quit(0)
	return false
