"""Robots described by data: a YAML spec over the user's own MJCF or URDF file.

`spec` reads and checks the file, `model` scales the model per design, `kinematics` is the
batched numeric leg IK any leg chain uses, `robot` the `Robot` a spec becomes, `discovery`
where specs are found, `new` writes a starting spec from a model file.
"""
