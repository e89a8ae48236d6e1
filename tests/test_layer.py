"""The glossy layer over a Principled BSDF's diffuse (smbs_addon/layer.py): the share of the light
it leaves the diffuse towards the eye, 1 - A(mu), against the smooth limit's exact Fresnel and
against what Cycles renders."""
import numpy as np
import pytest

from smbs_addon import layer

# Cycles 5.0.1 (the bpy module), measured: a plane of Blender's default Principled BSDF (Base
# Color 0.8, Roughness 0.5, IOR 1.5) and one of Diffuse BSDF 0.8 under a sun, seen by an
# orthographic camera at cosine mu, 64 spp; (Principled - Principled with Base Color black) /
# Diffuse is the diffuse's weight under the glossy layer (the black one holds the glossy alone)
CYCLES_DEFAULT = {1.0: 0.9626, 0.8: 0.9580, 0.6: 0.9439, 0.4: 0.9132, 0.356: 0.9030, 0.2: 0.8566}


def test_a_smooth_layer_takes_exactly_the_fresnel_reflectance():
    """Roughness 0: the layer is a perfect dielectric mirror, A = F(mu) exactly."""
    w = layer.layer_weights(1.5, 0.0)
    mu = np.linspace(0.0, 1.0, layer.MU_STEPS + 1)[1:]
    np.testing.assert_allclose(w[1:], 1.0 - layer.fresnel_dielectric(mu, 1.5), atol=5e-5)  # alpha 1e-4, not 0
    assert w[-1] == pytest.approx(0.96, abs=1e-9)  # F0 of IOR 1.5


@pytest.mark.parametrize("mu", sorted(CYCLES_DEFAULT))
def test_blenders_default_material_weighs_its_diffuse_as_cycles_does(mu):
    """Within 0.35% of Cycles from mu = 1 down to 0.356 (its lookup tables are coarse: 16-32 steps);
    at mu = 0.2 within 1%. Without the layer the caustic on such a floor read 1.15 of Cycles."""
    tab = layer.table(_one_material_scene((1.5, 0.5, 1.0)))
    ours = float(layer.weight(tab, np.array([0]), np.array([mu]))[0])
    assert ours == pytest.approx(CYCLES_DEFAULT[mu], rel=0.0035 if mu > 0.3 else 0.01)


def test_the_weight_is_one_exactly_without_a_layer_and_falls_with_the_layer():
    scene = _one_material_scene((0.0, 0.0, 0.0))
    assert not layer.has_layers(scene)
    tab = layer.table(scene)
    cos = np.linspace(-1.0, 1.0, 101)
    assert np.all(layer.weight(tab, np.zeros(101, np.int64), cos) == 1.0)  # bit for bit: x 1.0
    rough = [float(layer.weight(layer.table(_one_material_scene((1.5, r, 1.0))), np.array([0]), np.array([0.5]))[0])
             for r in (0.0, 0.5, 1.0)]
    assert 0.9 < rough[0] < rough[1] < rough[2] < 1.0  # rougher: less reflected at this slant
    tinted = layer.layer_weights(1.5, 0.5, 0.5)
    np.testing.assert_allclose(1.0 - tinted, 0.5 * (1.0 - layer.layer_weights(1.5, 0.5)), atol=1e-12)


def test_specular_ior_level_scales_the_reflectance_at_normal_incidence():
    eta, tint = layer.principled_layer(1.5, 0.5, (1.0, 1.0, 1.0))
    assert eta == pytest.approx(1.5) and tint == 1.0
    eta, tint = layer.principled_layer(1.5, 1.0, (0.2, 0.7, 0.4))
    assert ((eta - 1) / (eta + 1)) ** 2 == pytest.approx(0.08) and tint == pytest.approx(0.7)
    assert layer.principled_layer(1.5, 0.0, (1.0, 1.0, 1.0)) == (0.0, 0.0)


def _one_material_scene(lay):
    from smbs_addon import scene as S
    from smbs_addon.builder import SceneBuilder

    b = SceneBuilder()
    m = b.material("Floor", S.DIFFUSE, layer=lay)
    b.mesh("Floor", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]), m)
    b.set_camera(matrix=np.eye(4))
    return b.build()
