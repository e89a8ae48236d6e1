"""Rays and the camera in numpy: the embree scene and float64 hit records (tracer), Blender's camera
(camera), the film with its pixel filter and batches (film), and eye paths from film samples to
their first diffuse receiver (eye). Imports the layers below.
"""
