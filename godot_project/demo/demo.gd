## The demo: a character punches a sandbag with a policy trained by `punch train`. Pick a style, set the noise
## sigma and how many decisions get noise, and punch; every punch starts from the guard pose.
extends Node3D

const STYLES := ["straight", "hook", "swing"]
## Seconds between punches when "repeat" is on.
const REPEAT_PAUSE_S := 0.6

@onready var _character: Node3D = $PunchCharacter
@onready var _bag: RigidBody3D = $PunchSandbag/Bag
@onready var _controller: Node = $PunchController
@onready var _style: OptionButton = %Style
@onready var _sigma: HSlider = %Sigma
@onready var _sigma_value: Label = %SigmaValue
@onready var _noise_decisions: SpinBox = %NoiseDecisions
@onready var _repeat: CheckBox = %Repeat
@onready var _impact: Label = %Impact
@onready var _summary: Label = %Summary

var _bag_rest: Transform3D
var _punches := 0
var _repeat_timer := Timer.new()


func _ready() -> void:
	_bag_rest = _bag.global_transform
	_repeat_timer.one_shot = true
	_repeat_timer.wait_time = REPEAT_PAUSE_S
	_repeat_timer.timeout.connect(punch)
	add_child(_repeat_timer)
	for style in STYLES:
		_style.add_item(style)
	_style.item_selected.connect(func(index): _controller.policy = _policy_path(STYLES[index]))
	_sigma.value = _controller.noise_sigma
	_sigma.value_changed.connect(_on_sigma_changed)
	_on_sigma_changed(_sigma.value)
	_noise_decisions.value = _controller.noise_decisions
	_noise_decisions.value_changed.connect(func(value): _controller.noise_decisions = int(value))
	%Punch.pressed.connect(punch)
	_controller.hit.connect(_on_hit)
	_controller.punch_finished.connect(_on_punch_finished)
	punch.call_deferred()


## Back to the guard pose, the bag at rest, then a new punch.
func punch() -> void:
	_repeat_timer.stop()
	_character.reset_pose()
	_bag.global_transform = _bag_rest
	_bag.linear_velocity = Vector3.ZERO
	_bag.angular_velocity = Vector3.ZERO
	_impact.text = "impact: -"
	if _controller.punch():
		_punches += 1


func _policy_path(style: String) -> String:
	return "res://demo/policies/%s.onnx" % style


func _on_sigma_changed(value: float) -> void:
	_controller.noise_sigma = value
	_sigma_value.text = "%.2f" % value


func _on_hit(impulse: float, speed: float, _position: Vector3, _body: Node3D, _push: Vector3) -> void:
	_impact.text = "impact: %.1f m/s, %.2f N·s" % [speed, impulse]


func _on_punch_finished(metrics: Dictionary) -> void:
	_summary.text = "punch %d: peak fist speed %.1f m/s, %d hit(s), strongest %.2f N·s" % [
		_punches, metrics.peak_fist_speed_mps, metrics.hits, metrics.strongest_hit_ns]
	if _repeat.button_pressed:
		_repeat_timer.start()
