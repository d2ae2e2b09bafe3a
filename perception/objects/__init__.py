"""What a pick knows about objects: the object types, what they are made of, and their grasps.

:mod:`~perception.objects.object_spec` says what an object type is (its primitives, physics and
grasp, and the YuMi gripper's dimensions a grasp is checked against);
:mod:`~perception.objects.catalog` holds the types themselves (the sponge, spray bottle and mug,
the look-alike and the table clutter); :mod:`~perception.objects.grasps` chooses among an
object's symmetric grasps. Pure data and geometry (numpy only), so a model, the oracle, the
grasp judge and the simulator all read the same specs.
"""
