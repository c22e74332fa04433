"""Collision geometry: primitives, exact signed distances, the world, robot bodies as data."""
