"""Face Studio modeling core: cameras, pose recovery, RBF fitting, refinement, texturing, I/O.

Pure numpy/scipy/OpenCV; never imports Qt. Implements Pighin, Szeliski & Salesin,
*Modeling and Animating Realistic Faces from Images* (IJCV 2002), §5.
"""
