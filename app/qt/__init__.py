"""The studio's Qt widgets; everything Qt lives here (app/studio_state.py is the Qt-free state)."""
