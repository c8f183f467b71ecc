"""The caustic layer's line in the report (`plan.LayerFigures.text`) says each share
of the flux by what happened to it, in figures people read."""

from core.caustic_layer.plan import LayerFigures


def _text(**kw):
    return LayerFigures(layers=2, faces=800, rays=5000, flux_emitted=100.0, **kw).text()


def test_lost_and_outside_flux_are_said_apart():
    text = _text(flux_lost=12.0, flux_outside=26.0)
    assert text == (
        "800 texels and 5000 rays traced from the lights; of the flux, 12 % missed every receiver "
        "and 26 % landed outside the layers (past their edge)"
    )


def test_coarse_layers_out_of_view_are_said_as_drawn():
    # flux drawn by a coarse layer out of the camera's view is in the layers, not
    # "outside" (issue 28 item 6): the line says how many layers are coarse
    text = _text(flux_outside=0.4, coarse=1)
    assert text == (
        "800 texels and 5000 rays traced from the lights; of the flux, 0.4 % landed "
        "outside the layers (past their edge); 1 of the layers coarse, where the camera "
        "does not see the caustic (for reflections) or for a glass's faint light far from "
        "its caustic"
    )


def test_a_small_share_reads_under_a_tenth_of_a_percent_and_dust_is_not_said():
    """Issue 28 item 7: "1.3e-46 % of the flux missed" was floating-point dust (a
    millionth of the flux is far less than one of the 5000 rays carries)."""
    assert _text(flux_lost=1.3e-48) == "800 texels and 5000 rays traced from the lights"
    assert _text(flux_lost=1e-5) == "800 texels and 5000 rays traced from the lights"  # 1e-7 of it
    assert "under 0.1 % missed every receiver" in _text(flux_lost=0.05)  # 5e-4 of it
    assert "landed outside" not in _text(flux_lost=0.05)
    assert _text() == "800 texels and 5000 rays traced from the lights"
    assert "0.4 % landed outside" in _text(flux_outside=0.4)
