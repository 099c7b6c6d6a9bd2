"""Reading: arrays hold the file's cells, excitation × emission whatever the file's
orientation; missing cells are NaN and stay missing."""

import pickle

import numpy as np
import pytest

import fluorite


def test_bfc_cells_and_orientation(herpicer):
    m = fluorite.read(herpicer)
    # The grid line `380 780 10 49 300 10`: emission 380–780 (41), excitation 300–780 (49).
    assert m.excitation.dtype == np.float64 and m.values.dtype == np.float64
    np.testing.assert_array_equal(m.excitation, np.arange(300.0, 781.0, 10.0))
    np.testing.assert_array_equal(m.emission, np.arange(380.0, 781.0, 10.0))
    assert m.values.shape == (49, 41) == m.shape
    # Read off the file's text: rows are emission, columns excitation.
    # Row 380: column 300 is -0.00447876, column 380 (the diagonal) 0.0902205.
    assert m.values[0, 0] == -0.00447876
    assert m.values[8, 0] == 0.0902205
    # Row 390: column 300 is -0.00405812, column 390 is 0.0908112.
    assert m.values[0, 1] == -0.00405812
    assert m.values[9, 1] == 0.0908112
    # Row 440, column 440: 0.190512; row 550, column 550: 0.0262261.
    assert m.values[14, 6] == 0.190512
    assert m.values[25, 17] == 0.0262261
    assert m.kind == "surface" and m.preprocessing is None
    assert m.name == "HERPICER" and m.source == str(herpicer)
    assert m.has_diagonal and not m.per_nm


def test_wide_csv_with_emission_rows(measured):
    m = fluorite.read(measured[4])  # postit_pink.csv, corner em_nm\ex_nm
    assert m.values.shape == (49, 41)
    # Row 380 (emission), column 380 (excitation): 0.67145; row 390, column 390: 0.717173;
    # row 390, column 330: 2.45E-06.
    assert m.values[8, 0] == 0.67145
    assert m.values[9, 1] == 0.717173
    assert m.values[3, 1] == 2.45e-06


def test_csv_empty_and_nan_cells_are_missing(tmp_path):
    path = tmp_path / "holes.csv"
    path.write_text(
        "ex_nm\\em_nm,400,410,420\n"
        "400,0.5,,0.01\n"
        "410,NaN,0.6,0.02\n"
        "420,NA,0.001,0.7\n"
    )
    m = fluorite.read(path)
    expected = np.array([[0.5, np.nan, 0.01], [np.nan, 0.6, 0.02], [np.nan, 0.001, 0.7]])
    np.testing.assert_array_equal(m.values, expected)
    assert np.isnan(m.values).sum() == 3


def test_webfluor_zeros_are_missing(tmp_path):
    path = tmp_path / "tiny.txt"
    path.write_text(
        "300 310 320 330\n"
        "\n"
        "280 0 1200 3400 0\n"
        "\n"
        "270 0 0 2500 1800\n"
    )
    m = fluorite.read(path)
    assert m.kind == "instrument-eem"
    np.testing.assert_array_equal(m.excitation, [270.0, 280.0])
    np.testing.assert_array_equal(m.emission, [300.0, 310.0, 320.0, 330.0])
    expected = np.array([[np.nan, np.nan, 2500, 1800], [np.nan, 1200, 3400, np.nan]])
    values = m.values
    # Scatter masking may hide more cells, never reveal a zero.
    assert np.all(np.isnan(values[np.isnan(expected)]))
    kept = ~np.isnan(values)
    np.testing.assert_array_equal(values[kept], expected[kept])
    assert m.preprocessing is not None and m.preprocessing["zeros_missing"] >= 0


def test_shared_webfluor_eem(shared_eems):
    m = fluorite.read(shared_eems[0])
    assert m.kind == "instrument-eem"
    pre = m.preprocessing
    assert pre["units"] == "arbitrary"
    # WebFluor zeros mean "not measured": the reader makes them missing and says so.
    assert any("holding 0 read as missing" in note for note in m.notes)
    assert np.isnan(m.values).any()
    assert not m.has_diagonal and m.arbitrary_scale
    # No cell that the file holds as 0 is anything but missing.
    assert not np.any(m.values == 0.0)


def test_measurement_from_arrays_keeps_nan():
    ex = np.arange(400.0, 431.0, 10.0)
    em = np.arange(400.0, 441.0, 10.0)
    values = np.full((4, 5), 0.001)
    for i in range(4):
        values[i, i] = 0.5
    values[1, 3] = np.nan
    values[3, 0] = np.nan
    m = fluorite.Measurement(ex, em, values, name="made")
    assert m.name == "made" and m.kind == "surface"
    out = m.values
    assert out.shape == (4, 5)
    assert np.isnan(out[1, 3]) and np.isnan(out[3, 0])
    assert np.isnan(out).sum() == 2
    np.testing.assert_array_equal(np.nan_to_num(out, nan=-1), np.nan_to_num(values, nan=-1))
    # A copy: changing the array does not change the measurement.
    out[0, 0] = 9.0
    assert m.values[0, 0] == 0.5
    # Lists work too, and pickling keeps everything.
    again = fluorite.Measurement(list(ex), list(em), values.tolist(), name="made")
    np.testing.assert_array_equal(np.isnan(again.values), np.isnan(values))
    restored = pickle.loads(pickle.dumps(m))
    np.testing.assert_array_equal(np.nan_to_num(restored.values, nan=-1), np.nan_to_num(values, nan=-1))
    assert restored.name == "made" and restored.kind == "surface"


def test_measurement_shape_is_checked():
    ex = [400.0, 410.0, 420.0]
    em = [400.0, 410.0]
    with pytest.raises(fluorite.FluoriteError, match=r"shape \(2, 3\), expected .* \(3, 2\)"):
        fluorite.Measurement(ex, em, np.zeros((2, 3)))
    with pytest.raises(fluorite.FluoriteError, match="strictly increasing|increas"):
        fluorite.Measurement([410.0, 400.0, 420.0], em, np.zeros((3, 2)) + 0.1)
    with pytest.raises(fluorite.FluoriteError, match="infinite"):
        fluorite.Measurement(ex, em, np.array([[0.1, np.inf], [0.1, 0.1], [0.1, 0.1]]))
    with pytest.raises(fluorite.FluoriteError, match="no cell holds a measured value"):
        fluorite.Measurement(ex, em, np.full((3, 2), np.nan))
    with pytest.raises(ValueError):  # FluoriteError is a ValueError
        fluorite.Measurement(ex, em, "not an array")


def test_fit_of_a_measurement_with_missing_cells(measured):
    m = fluorite.read(measured[1])
    values = m.values
    values[20:25, 10:15] = np.nan
    holed = fluorite.Measurement(m.excitation, m.emission, values, name="holed")
    fit = fluorite.fit(holed, model="tabulated")
    assert fit.material is not None
    assert np.isnan(fit.measurement.values[20:25, 10:15]).all()
    predicted = fit.predicted
    assert predicted.shape == values.shape and np.isfinite(predicted).all()
