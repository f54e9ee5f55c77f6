## A character, its sandbag and a PunchController, kept apart from other pairs in the same physics world by
## two collision layers of their own (one for the character, one for the bag, masks two-sided as in the
## training world). Shared by the measuring tools (evaluate.gd, the evaluator's one driver, and idle_cost.gd) and
## render.gd, with the command-line reading and the physics worlds they all use.
extends RefCounted

const CHARACTER_SCENE := preload("res://addons/punch_controller/scenes/punch_character.tscn")
const SANDBAG_SCENE := preload("res://addons/punch_controller/scenes/punch_sandbag.tscn")
## A world holds at most 16 pairs: two of its 32 collision layers each.
const MAX_PER_WORLD := 16


## Adds the pair under `parent`: the character at `origin`, the bag's centre at `origin + bag_offset`, on the
## layers of `slot` (0 to 15) of their world, the bag swinging at `bag_velocity` (m/s, horizontal). The
## controller plays `policy` with `sigma`; it is not started.
static func add(parent: Node, slot: int, origin: Vector3, bag_offset: Vector3, policy: String, sigma: float,
		noise_decisions: int, seed: int, bag_velocity := Vector3.ZERO) -> Node:
	var character_layer := 1 << (2 * slot)
	var character: Node3D = CHARACTER_SCENE.instantiate()
	character.position = origin
	set_layers(character, character_layer, character_layer << 1)
	parent.add_child(character)
	var sandbag: Node3D = SANDBAG_SCENE.instantiate()
	sandbag.position = origin + bag_offset
	set_layers(sandbag, character_layer << 1, character_layer)
	parent.add_child(sandbag)
	if bag_velocity != Vector3.ZERO:
		# Swinging on its rope: the bag turns about the hook as it moves (ω = r × v / |r|²), as in training.
		var bag: RigidBody3D = sandbag.get_node("Bag")
		var arm := bag.global_position - (sandbag.get_node("Hook") as Node3D).global_position
		bag.linear_velocity = bag_velocity
		bag.angular_velocity = arm.cross(bag_velocity) / arm.length_squared()
	var controller: Node = ClassDB.instantiate("PunchController")
	controller.set("character", character)
	controller.set("target", sandbag.get_node("Bag"))
	controller.set("policy", load(policy))
	controller.set("noise_sigma", sigma)
	controller.set("noise_decisions", noise_decisions)
	controller.set("seed", seed)
	parent.add_child(controller)
	return controller


## Fills `options` (name -> default text) from the command line's user arguments (`--name=value`); returns
## the error for an argument it does not know, for a `required` one left empty, or for a `policy` file that is
## not there; else "".
static func read_options(options: Dictionary, required: Array[String] = []) -> String:
	for argument in OS.get_cmdline_user_args():
		var parts := argument.trim_prefix("--").split("=", true, 1)
		if parts.size() != 2 or not options.has(parts[0]):
			return "unknown argument '%s' (expected --%s=VALUE)" % [argument, "=VALUE, --".join(options.keys())]
		options[parts[0]] = parts[1]
	if required.any(func(name: String) -> bool: return options[name] == ""):
		return "--%s are needed" % ", --".join(required)
	if required.has("policy") and not FileAccess.file_exists(options.policy):
		return "policy file not found: %s" % options.policy
	return ""


## The numbers of a comma-separated option ("0,0.3").
static func floats(text: String) -> PackedFloat32Array:
	var values := PackedFloat32Array()
	for value in text.split(","):
		values.append(float(value))
	return values


## The list a JSON file holds, or [] for a file that holds none.
static func json_list(path: String) -> Array:
	var parsed = JSON.parse_string(FileAccess.get_file_as_string(path))
	return parsed if parsed is Array else []


## A physics world of its own under `parent`, never rendered: room for MAX_PER_WORLD pairs.
static func add_arena(parent: Node) -> SubViewport:
	var arena := SubViewport.new()
	arena.own_world_3d = true
	arena.render_target_update_mode = SubViewport.UPDATE_DISABLED
	parent.add_child(arena)
	return arena


## Frees a finished batch's physics worlds (`add_arena`'s) and empties the list.
static func free_arenas(arenas: Array[SubViewport]) -> void:
	for arena in arenas:
		arena.get_parent().remove_child(arena)
		arena.free()
	arenas.clear()


## Sizes `character`'s arms through `PunchCharacter.size_arms`: its upper arm and forearm (elbow to fist centre)
## times `scale` (x: upper arm, y: forearm), from the lengths it reports for its own scene (`arm_lengths()`), the
## shoulders as they are. Returns "" or, for a size it refuses (its error is printed above), what it accepts.
static func size_arms(character: Node, scale: Vector2) -> String:
	if scale == Vector2.ONE:
		return ""
	var own: Vector3 = character.call("arm_lengths")
	if character.call("size_arms", own.x * scale.x, own.y * scale.y, own.z):
		return ""
	var accepted: Vector2 = character.call("arm_scale_range")
	var label := str(scale.x) if scale.x == scale.y else "%sx%s" % [scale.x, scale.y]
	return ("PunchCharacter.size_arms refused the arm scale %s (it accepts %s to %s times the scene's arm; its error "
		% [label, accepted.x, accepted.y] + "is above)")


## Writes a measuring tool's result, `data` as JSON, to `path`.
static func write_json(path: String, data: Dictionary) -> void:
	var out := FileAccess.open(path, FileAccess.WRITE)
	out.store_string(JSON.stringify(data))
	out.close()


static func set_layers(scene_root: Node, layer: int, mask: int) -> void:
	for body in scene_root.find_children("*", "CollisionObject3D", true, false):
		body.collision_layer = layer
		body.collision_mask = mask
