"""Serial arms: DH and product-of-exponentials kinematics, analytic and numerical IK."""
