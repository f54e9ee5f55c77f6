"""Facts of the addon's character and sandbag scenes that the reward and the simulator both measure against."""

SCENE_ARM_LENGTHS_M = (0.282, 0.337, 0.36)
"""the character scene's own upper arm, forearm (elbow to fist centre) and shoulder width, m"""
SCENE_BAG_RADIUS_M = 0.175
"""the sandbag scene's radius, m (an upright cylinder)"""
