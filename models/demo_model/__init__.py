"""The shipped demo model (made by tools/make_demo_model.py); a package so wheels include it."""
