"""se3ocp: geometrically exact optimal control of a rigid body on SE(3)."""
