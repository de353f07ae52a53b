"""The bundled demo scans, installed as the package data ``rough_viewer.demo_data``.

Found with ``importlib.resources.files("rough_viewer.demo_data")`` (see
:mod:`rough_viewer.synthetic.demos`), so a wheel install opens its demo as a clone does.
"""
