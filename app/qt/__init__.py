"""The studio's Qt widgets; everything Qt lives here (app/model.py is the Qt-free state)."""
