"""Fast renderers of a world's scene (docs/rendering.md), besides PyBullet's, which stays the reference:

    raster.py, raster_ground.py, raster_objects.py   renderer "numba": a rasteriser compiled with numba that
                                                      paints the ground as OpenCV and draws the objects as
                                                      TinyRenderer, rule for rule
    gl_*.py                                           renderer "gl": OpenGL through moderngl, headless EGL (Mesa's
                                                      llvmpipe on a CPU, a GPU's driver where there is one)
    lighting.py                                       colours as TinyRenderer holds them, for both
    available.py                                      whether this process can run each of them
"""
