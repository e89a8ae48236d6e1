"""Files: EXR images with their statistics in the header (exr). Imports core only.
"""
