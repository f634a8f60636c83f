"""Reading CSV data files with a title line, a names row and a units row."""
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow.curves import DataFileError, read_table

EXAMPLE_CSV = Path(__file__).resolve().parents[2] / "examples" / "latex_balloon_60mm_pv.csv"


def write(tmp_path, text, name="data.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------
# the measured latex balloon file
# ---------------------------------------------------------------------------------------
def test_example_file_layout():
    t = read_table(EXAMPLE_CSV)
    assert t.names == ["Time", "Volume", "Pressure"]
    assert [str(u) for u in t.units] == ["second", "milliliter", "millibar"]
    assert t.data.shape == (56, 3)
    assert t.first_data_line == 4          # title, names, units, then data
    np.testing.assert_array_equal(t.data[0], [14.31, 1.0, 22.0])
    np.testing.assert_array_equal(t.data[-1], [254.65, 55.66, 1060.0])


def test_example_file_columns_in_si():
    t = read_table(str(EXAMPLE_CSV))          # a str path works as well as a Path
    v = t.column("Volume", "m**3")
    p = t.column("Pressure", "Pa")
    time = t.column("Time", "s")
    assert v.shape == p.shape == time.shape == (56,)
    assert v[0] == pytest.approx(1e-6, rel=1e-12)
    assert v[-1] == pytest.approx(55.66e-6, rel=1e-12)
    assert p[0] == pytest.approx(2200.0, rel=1e-12)          # gauge, as in the file
    assert p[-1] == pytest.approx(106000.0, rel=1e-12)
    assert time[1] == pytest.approx(17.01, rel=1e-12)
    # other target units convert too
    np.testing.assert_allclose(t.column("Volume", "ml"), t.data[:, 1], rtol=1e-12)


def test_column_names_are_case_insensitive():
    t = read_table(EXAMPLE_CSV)
    np.testing.assert_array_equal(t.column("volume", "m**3"), t.column(" VOLUME ", "m**3"))


def test_unknown_column_lists_the_columns():
    t = read_table(EXAMPLE_CSV)
    with pytest.raises(DataFileError, match=r"no column named 'Flow'.*'Time', 'Volume'"):
        t.column("Flow", "m**3/s")


def test_column_with_incompatible_unit():
    t = read_table(EXAMPLE_CSV)
    with pytest.raises(sf.UnitError, match=r"column 'Volume' is in ml.*Pa"):
        t.column("Volume", "Pa")


def test_read_table_is_exported():
    assert sf.read_table is read_table
    assert issubclass(DataFileError, ValueError)


# ---------------------------------------------------------------------------------------
# other layouts
# ---------------------------------------------------------------------------------------
def test_without_title_line(tmp_path):
    path = write(tmp_path, "Time,Volume,Pressure\ns,l,kPa\n0,0.5,1\n1,1.5,2\n")
    t = read_table(path)
    assert t.first_data_line == 3
    np.testing.assert_allclose(t.column("Volume", "m**3"), [5e-4, 1.5e-3], rtol=1e-12)
    np.testing.assert_allclose(t.column("Pressure", "Pa"), [1e3, 2e3], rtol=1e-12)


def test_offset_units_convert_with_their_offset(tmp_path):
    # plain scalings take a cached factor; degC -> K is not one and goes through pint
    path = write(tmp_path, "Time,Temperature\nmin,degC\n0,20\n1,-273.15\n")
    t = read_table(path)
    np.testing.assert_allclose(t.column("Temperature", "K"), [293.15, 0.0], atol=1e-12)
    np.testing.assert_allclose(t.column("Time", "s"), [0.0, 60.0], rtol=1e-15)


def test_without_units_row(tmp_path):
    path = write(tmp_path, "Title line,x,y\nTime,Volume,Pressure\n0,1,10\n1,2,20\n")
    t = read_table(path)
    assert t.names == ["Time", "Volume", "Pressure"]
    assert t.units is None
    with pytest.raises(DataFileError, match="no unit"):
        t.column("Volume", "m**3")
    np.testing.assert_allclose(t.column("Volume", "m**3", default_unit="ml"), [1e-6, 2e-6])


def test_blank_lines_and_whitespace_are_ignored(tmp_path):
    path = write(tmp_path, "Time, Volume , Pressure\n\n s , ml , mbar \n\n1, 1 ,22\n\n2,2,25\n")
    t = read_table(path)
    assert t.names == ["Time", "Volume", "Pressure"]
    assert t.data.shape == (2, 3)
    assert t.first_data_line == 5
    np.testing.assert_allclose(t.column("Pressure", "Pa"), [2200.0, 2500.0])


def test_utf8_bom_is_ignored(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n2,2,25\n".encode("utf-8-sig"))
    assert read_table(path).names[0] == "Time"


# ---------------------------------------------------------------------------------------
# bad files
# ---------------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothere.csv"):
        read_table(tmp_path / "nothere.csv")


TITLED = "Balloon,2017-11-16,X\nTime,Volume,Pressure\n"


@pytest.mark.parametrize("content, fragments", [
    pytest.param(TITLED + "s,mll,mbar\n1,1,22\n2,2,25\n",
                 ["line 3", "'mll'", "data.csv"], id="unknown_unit_in_units_row"),
    pytest.param(TITLED + "s,ml,mbar\n1,1,22\n2,2,25\n3,3,abc\n4,4,30\n",
                 ["line 6", "'abc'", "'Pressure'"], id="non_numeric_cell_names_the_line"),
])
def test_error_message_names_line_and_cell(tmp_path, content, fragments):
    path = write(tmp_path, content)
    with pytest.raises(DataFileError) as info:
        read_table(path)
    msg = str(info.value)
    for fragment in fragments:
        assert fragment in msg


def test_non_numeric_cell_in_first_data_row_is_reported_as_not_a_number(tmp_path):
    path = write(tmp_path, "Time,Volume,Pressure\ns,ml,mbar\n1,1,2x2\n2,2,25\n")
    with pytest.raises(DataFileError) as info:
        read_table(path)
    msg = str(info.value)
    assert "'2x2'" in msg and "not a number" in msg


@pytest.mark.parametrize("content, match", [
    pytest.param("Time,Volume,Pressure\ns,ml,furlongs_per_x\n1,1,22\n2,2,25\n", r"line 2.*'furlongs_per_x'", id="unknown_unit_without_title_line"),
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n2,,25\n", r"line 4.*'Volume'", id="empty_cell_names_the_line"),
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,2x2\n2,2,25\n", "line 3", id="non_numeric_cell_in_first_data_row_names_the_line"),
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n2,2\n", r"line 4: expected 3 cells, got 2", id="row_with_missing_cells"),
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n", "no numeric data", id="no_data_rows"),
    pytest.param("1,1,22\n2,2,25\n", "no column-names row", id="no_names_row"),
    pytest.param("Time,Volume\n1,1,22\n2,2,25\n", "line 1: 2 column names for 3 data columns", id="names_row_with_wrong_length"),
])
def test_bad_file_is_reported_with_its_line(tmp_path, content, match):
    path = write(tmp_path, content)
    with pytest.raises(DataFileError, match=match):
        read_table(path)
