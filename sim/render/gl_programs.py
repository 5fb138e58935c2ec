"""The GLSL programs: one that draws a view's ground and objects in a single call, and TinyRenderer's lighting.

A vertex is a point of the ground or of an object (`kind`, below). The ground is flat and painted in its materials'
order, not by depth, as sim/ground_painter.py paints it: each ground vertex carries its material's rank, which
becomes its depth (a later material is nearer), and its colour as the painter's. Objects are lit per pixel as
PyBullet's TinyRenderer lights them (sim/render/raster_objects.py), without shadows or specular light, and their
depth is squeezed in front of every ground rank: every object stands on the ground, so nothing of it is in front.
Beyond the far plane nothing is drawn, as TinyRenderer draws nothing there (the insets' cameras see 150 m and cull
at 120 m).

Cars are instances: the car's pose and paint are per instance; the static scenery is instance 0, which does not move
it. Pixel offsets (`ground_shift`, `object_shift`, in NDC) align the ground with the painter's pixel grid and the
objects with TinyRenderer's, which samples a pixel at its corner rather than its centre.
"""
from __future__ import annotations

GROUND, OBJECT, PAINTED = 0.0, 1.0, 2.0   # kinds of vertex: ground, object of its own colour, a car's paint
GROUND_DEPTH = (0.9, 0.1)     # NDC depth of ground rank r: 0.9 - 0.1 r (ranks 0-4: 0.9 to 0.5)
OBJECT_DEPTH = (0.7, -0.3)    # an object's NDC depth z becomes 0.7 z - 0.3: from -1 to 0.4, before any ground

VERTEX = f"""
#version 330
uniform mat4 view_projection;
uniform vec2 ground_shift;
uniform vec2 object_shift;
in vec3 in_position;      // [m] world (ground, scenery) or car frame (cars)
in vec3 in_normal;
in vec3 in_colour;        // 0-255: the ground's painted colour, an object's base colour
in float in_kind;         // {GROUND:g} ground, {OBJECT:g} object, {PAINTED:g} a car's paint (colour from the instance)
in float in_rank;         // the ground material's painting rank
in vec2 in_place;         // instance: x, y [m]
in vec2 in_heading;       // instance: cos, sin of yaw
in vec3 in_paint;         // instance: 0-255
out vec3 normal;
flat out vec3 base;
flat out float ground;
void main() {{
    vec2 c = in_heading;
    vec3 p = vec3(c.x * in_position.x - c.y * in_position.y + in_place.x,
                  c.y * in_position.x + c.x * in_position.y + in_place.y, in_position.z);
    gl_Position = view_projection * vec4(p, 1.0);
    normal = vec3(c.x * in_normal.x - c.y * in_normal.y, c.y * in_normal.x + c.x * in_normal.y, in_normal.z);
    base = in_kind == {PAINTED:g} ? in_paint : in_colour;
    ground = in_kind == {GROUND:g} ? 1.0 : 0.0;
    if (in_kind == {GROUND:g}) {{
        gl_Position.xy += ground_shift * gl_Position.w;
        gl_Position.z = ({GROUND_DEPTH[0]:g} - {GROUND_DEPTH[1]:g} * in_rank) * gl_Position.w;
        gl_ClipDistance[0] = 1.0;
    }} else {{
        gl_Position.xy += object_shift * gl_Position.w;
        gl_ClipDistance[0] = gl_Position.w - gl_Position.z;   // the far plane, which the squeezed depth no longer is
        gl_Position.z = {OBJECT_DEPTH[0]:g} * gl_Position.z + ({OBJECT_DEPTH[1]:g}) * gl_Position.w;
    }}
}}
"""

# lit per pixel from the interpolated normal, as TinyRenderer does (a guard rail's normals turn along a bend)
FRAGMENT = """
#version 330
uniform vec3 light;
uniform float ambient;
uniform float diffuse;
in vec3 normal;
flat in vec3 base;
flat in float ground;
out vec4 frag;
void main() {
    if (ground > 0.5) {
        frag = vec4(base / 255.0, 1.0);
    } else {
        float d = max(0.0, dot(normalize(normal), light));
        frag = vec4(min(floor(ambient * base + (diffuse * d) * base), 255.0) / 255.0, 1.0);
    }
}
"""
