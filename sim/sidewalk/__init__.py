"""The sidewalk world (docs/sidewalk.md): a 1/10-scale car with a stereo camera on winding sidewalks, park and
forest paths, after Chowdhuri, Pankaj and Zipser, MultiNet, 2017.

    paths.py      path files, presets and procedural loops (the highway's Track/Straight/Arc geometry)
    layout.py     what stands where: borders (hedges, bush rows), obstacles, trees; from a path and a seed
    car.py        the car: steer/motor in [0, 1], a kinematic bicycle in path coordinates
    lead.py       the lead car of follow mode
    truth.py      the exact per-step truth record (SIDEWALK's fields), from geometry
    look.py       seeded appearance: colours, sun, time of day
    scenery.py    meshes and ground polygons of a layout, in chunks
    painter.py    the objects' rasteriser (flat-shaded convex pieces, painter's algorithm, OpenCV)
    stereo.py     the stereo rig and the renderer of both cameras
    world.py      SidewalkWorld: all of it stepped together
    topdown.py    a top-down picture of the world around the car (videos, docs)
    gym_env.py    drivestudio/Sidewalk-v0
"""
