"""Every public component documents every constructor parameter, and every
numeric parameter its unit in brackets (DESIGN rule 2: ``diameter : float [m]``)."""
import inspect
import re

import pytest

import softflow as sf

COMPONENTS = [getattr(sf, n) for n in sf.__all__
              if inspect.isclass(getattr(sf, n)) and issubclass(getattr(sf, n), sf.LibraryComponent)
              and getattr(sf, n) is not sf.LibraryComponent]
NON_NUMERIC = ("{", "str", "bool", "Fluid", "PVCurve", "callable", "Waveform", "HysteresisLoop")


def _entry(doc, name):
    """The type description after 'name :' (or 'a, name, b :') in a numpydoc list."""
    for line in doc.splitlines():
        head, sep, desc = line.partition(" : ")
        if sep and name in [h.strip() for h in head.split(",")]:
            return desc.strip()
    return None


def test_there_are_components_to_check():
    assert len(COMPONENTS) >= 12


@pytest.mark.parametrize("cls", COMPONENTS, ids=lambda c: c.__name__)
def test_every_parameter_is_documented_with_its_unit(cls):
    doc = inspect.getdoc(cls) or ""
    params = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    missing = [p for p in params if _entry(doc, p) is None]
    assert not missing, f"{cls.__name__}: undocumented parameters {missing}"
    no_unit = [(p, _entry(doc, p)) for p in params
               if not _entry(doc, p).startswith(NON_NUMERIC) and not re.search(r"\[.*\]", _entry(doc, p))]
    assert not no_unit, f"{cls.__name__}: parameters without a [unit]: {no_unit}"
