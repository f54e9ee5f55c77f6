## A partner's pads: one character throws the six moves in order (1 jab ... 6 rear uppercut) at the focus mitts a
## partner presents, each mitt held on the punching hand's side where that move meets its target (a straight's
## face to the fist's side, a hook's turned toward the fist, an uppercut's higher and tilted down); after the six,
## the stance flips between orthodox and southpaw. A struck mitt gives way along the punch and comes back, as a
## holder's arm does. Prints the share of punches that hit the mitt presented.
extends "res://demo/arena.gd"

const MOVES: Array[StringName] = [&"jab", &"cross", &"lead_hook", &"rear_hook", &"lead_uppercut", &"rear_uppercut"]
## How far the partner stands from the puncher (m).
const PARTNER_DISTANCE_M := 1.0
## A big focus mitt's face (m): wide, tall, thick.
const PAD_SIZE_M := Vector3(0.26, 0.4, 0.06)
## Where a mitt is held for each kind of move. The mitt's origin, the point the punch aims at, is where a sandbag's
## centre would be for that punch (`aim`, in the puncher's frame, m; the policies aim at a bag's centre), and its face
## is where that punch meets a bag's surface (`face`, from the aim; x toward the punching hand's side), turned as a
## holder turns a mitt into the punch (degrees: `yaw` toward the fist's side, `pitch` facing down).
const HOLDS := {
	&"straight": {"aim": Vector3(0.0, 1.38, 0.72), "face": Vector3(0.10, 0.07, -0.18), "yaw": 0.0, "pitch": 0.0},
	&"hook": {"aim": Vector3(0.0, 1.38, 0.72), "face": Vector3(0.0, -0.04, -0.18), "yaw": 20.0, "pitch": 0.0},
	&"uppercut": {"aim": Vector3(0.0, 1.3, 0.72), "face": Vector3(0.055, 0.2, -0.18), "yaw": 0.0, "pitch": 30.0},
}
## Where the other mitt waits, by the partner's glove (x: +1 on the idle mitt's side).
const REST := Vector3(0.2, 1.45, 0.7)
## How far a struck mitt gives way (m) and how long it takes to come back (s).
const GIVE_M := 0.05
const GIVE_S := 0.25
## Physics frames a mitt is held still where it goes before the punch at it starts.
const HOLD_FRAMES := 3

var _controller: PunchController
var _pads: Dictionary = {}  # &"left" / &"right" (the puncher's side) -> AnimatableBody3D
var _give: Tween
var _move_label := Label3D.new()
var _move_index := 0
var _landed := false


func _ready() -> void:
	build_stage(Vector3(-2.6, 2.2, 0.5))
	get_viewport().get_camera_3d().look_at_from_position(Vector3(-1.9, 1.75, 0.3), Vector3(0.0, 1.3, 0.5))
	add_sky(self)
	var puncher := add_character(self, Transform3D.IDENTITY)
	_controller = add_controller(puncher, null, 0.1, 1)
	add_controller(add_character(self, Transform3D(Basis(Vector3.UP, PI), Vector3(0, 0, PARTNER_DISTANCE_M))), null, 0.0, 2)
	for side in [&"left", &"right"]:
		_pads[side] = _add_pad()
	_move_label.position = Vector3(0, 1.95, 0.5)
	_move_label.pixel_size = 0.006
	_move_label.font_size = 36
	_move_label.outline_size = 12
	_move_label.billboard = BaseMaterial3D.BILLBOARD_ENABLED
	add_child(_move_label)
	_controller.hit.connect(_on_hit)
	_controller.punch_finished.connect(func(_metrics):
		count_punch(_landed, "pads")
		_landed = false)
	_controller.recovered.connect(_next)
	_throw.call_deferred()


## A mitt: a body the game moves (the partner's hold), its box and its red mesh (the body's children 0 and 1).
func _add_pad() -> AnimatableBody3D:
	var pad := AnimatableBody3D.new()
	pad.collision_layer = 4  # where sandbags are: the layer fists strike and `hit` reports
	pad.sync_to_physics = false  # moved at once where the partner holds it
	var shape := CollisionShape3D.new()
	shape.shape = BoxShape3D.new()
	shape.shape.size = PAD_SIZE_M
	pad.add_child(shape)
	var mesh := MeshInstance3D.new()
	mesh.mesh = BoxMesh.new()
	mesh.mesh.size = PAD_SIZE_M
	var material := StandardMaterial3D.new()
	material.albedo_color = Color(0.8, 0.15, 0.12)
	mesh.material_override = material
	pad.add_child(mesh)
	add_child(pad)
	return pad


## The presented mitt struck: it gives way along the punch, then comes back to where it is held.
func _on_hit(_impulse: float, _speed: float, _position: Vector3, body: Node3D, push: Vector3, _hand: StringName,
		_part: StringName, _blocked: bool) -> void:
	if body != _controller.target:
		return
	_landed = true
	var held: Vector3 = body.position
	_give = create_tween()
	_give.tween_property(body, "position", held + push.normalized() * GIVE_M, 0.05)
	_give.tween_property(body, "position", held, GIVE_S)


## The next move after a recovery: the six in order, then the other stance.
func _next() -> void:
	_move_index += 1
	if _move_index % MOVES.size() == 0:
		_controller.stance = PunchController.SOUTHPAW if _controller.stance == PunchController.ORTHODOX else PunchController.ORTHODOX
	_throw()


## Presents the mitt on the move's hand's side where that move lands (+X is the puncher's left), the other by the
## partner's face, and throws the move at it.
func _throw() -> void:
	var move := MOVES[_move_index % MOVES.size()]
	var hand := PunchController.hand_for(move, _controller.stance)
	var kind := &"hook" if String(move).ends_with("hook") else (&"uppercut" if String(move).ends_with("uppercut") else &"straight")
	var hold: Dictionary = HOLDS[kind]
	var side := 1.0 if hand == &"left" else -1.0
	if _give != null:
		_give.kill()  # the last mitt goes where it is held next, not back where it was struck
	for pad_side in _pads:
		var pad: AnimatableBody3D = _pads[pad_side]
		var sign := 1.0 if pad_side == &"left" else -1.0
		var face := Transform3D(Basis.IDENTITY, Vector3(0.0, 0.0, REST.z))
		if pad_side == hand:
			var aim: Vector3 = hold.aim
			var offset: Vector3 = hold.face
			pad.position = Vector3(aim.x * side, aim.y, aim.z)
			face = Transform3D(Basis.from_euler(Vector3(deg_to_rad(-hold.pitch), deg_to_rad(-hold.yaw * side), 0.0)),
				Vector3(offset.x * side, offset.y, offset.z))
		else:
			pad.position = Vector3(REST.x * sign, REST.y, 0.0)
		for child in pad.get_children():
			child.transform = face
	_controller.target = _pads[hand]
	var stance_name := "orthodox" if _controller.stance == PunchController.ORTHODOX else "southpaw"
	_move_label.text = "%d %s\n%s, %s hand" % [MOVES.find(move) + 1, String(move).replace("_", " "), stance_name, hand]
	# The mitt is still before the punch starts: a target that jumps reads as one moving fast.
	for frame in HOLD_FRAMES:
		await get_tree().physics_frame
	_controller.punch(move)
