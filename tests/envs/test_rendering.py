"""rgb_array frames and the human window (drawn off-screen with matplotlib's Agg backend)."""

import numpy as np

from .conftest import NO_CONTACT


def test_rgb_array_frame_shape_and_motion(make_env):
    env = make_env(render_mode="rgb_array", render_height=128)
    env.reset(seed=0, options=NO_CONTACT)
    f0 = env.render()
    assert f0.shape == (128, 256, 3) and f0.dtype == np.uint8
    for _ in range(5):
        env.step(np.array([1, 0, 0, 0, 0, 0], np.float32))
    f1 = env.render()
    assert f1.shape == f0.shape and not np.array_equal(f0[:, :128], f1[:, :128])
    assert f1 is not env.render()  # a fresh array each call


def test_human_mode_renders_on_step_and_returns_none(make_env):
    env = make_env(render_mode="human")
    env.reset(seed=0)
    env.step(np.zeros(6, np.float32))
    assert env.render() is None
    assert env.unwrapped._renderer._fig is not None
    env.close()
    assert env.unwrapped._renderer._fig is None


def _text_at(frame_half, text, scale):
    """Does ``frame_half`` show ``text`` (black on its white box) at the frame's text place?"""
    from brush_env.envs.glyphs import text_mask
    from brush_env.envs.rendering import BLACK, WHITE

    mask = text_mask(text, scale)
    r = c = 2 * scale
    region = frame_half[r : r + mask.shape[0], c : c + mask.shape[1]]
    return bool(np.all(region[mask] == BLACK) and np.all(region[~mask] == WHITE))


def test_frames_carry_time_force_against_its_limit_and_coverage(make_env):
    """The video frames say what they show (issue 31): t and coverage on the left, the total
    normal force and its safe limit on the right, as numbers the env reports."""
    from brush_env.envs.rendering import frame_texts

    env = make_env(render_mode="rgb_array", render_height=256)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([0.3, 0, -1, 0, 0, 0], np.float32))
    u = env.unwrapped
    frame = env.render()
    left, right = frame_texts(
        u._last.time, u.coverage.fraction, u._total_force, u.config.total_force_limit
    )
    assert left.startswith(f"t {u._last.time:.2f} s  coverage ") and left.endswith(" %")
    assert right.endswith(f"limit {u.config.total_force_limit:g} N")
    assert _text_at(frame[:, :256], left, 1)
    # below the limit the force is written in black; text pixels are there, not only the box
    assert u._total_force <= u.config.total_force_limit and _text_at(frame[:, 256:], right, 1)
    env.step(np.array([0.3, 0, 0, 0, 0, 0], np.float32))
    later = frame_texts(u._last.time, u.coverage.fraction, u._total_force, 4.0)[0]
    assert later != left and not _text_at(env.render()[:, :256], left, 1)


def test_the_font_refuses_a_character_it_lacks():
    import pytest

    from brush_env.envs.glyphs import text_mask

    assert text_mask("t 1.5 s", 2).shape == (14, 2 * 6 * 7)
    with pytest.raises(ValueError, match=r"no glyph for \['Z'\]"):
        text_mask("Zt")
