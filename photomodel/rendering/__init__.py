"""The one renderer (moderngl on EGL) and the view-dependent texturing shaders."""
