"""How light scatters and shines, in Cycles' conventions, written once as compiled per-lane functions
(with array forms for numpy callers).

optics (reflect, refract, the specular scatter of a path), fresnel (Fresnel terms and lobe
weights), microfacet (GGX: Lambda, visible normals), energy (Multiscatter GGX's compensation), coat
(Principled coats, Oren-Nayar), thinfilm (iridescence), absorption (Volume Absorption inside glass),
lights (emission, photons leaving lights), light_samples (a chain's light end). Imports core and
scene.
"""
