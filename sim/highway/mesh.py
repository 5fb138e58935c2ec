"""A plain triangle mesh container shared by the scenery and the car models; the renderer takes these."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass
class MeshData:
    vertices: np.ndarray  # (n, 3) [m]
    faces: np.ndarray     # (m, 3) vertex indices, counter-clockwise seen from outside
    normals: np.ndarray   # (n, 3) unit vertex normals

    @staticmethod
    def concat(meshes: list[MeshData]) -> MeshData:
        offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        return MeshData(np.vstack([m.vertices for m in meshes]),
                        np.vstack([m.faces + o for m, o in zip(meshes, offsets)]),
                        np.vstack([m.normals for m in meshes]))

    @staticmethod
    def from_trimesh(m: trimesh.Trimesh) -> MeshData:
        """Flat-shaded copy: one vertex per face corner, each carrying its face's normal."""
        tri = np.asarray(m.vertices, dtype=np.float64)[np.asarray(m.faces)]
        n_faces = len(tri)
        return MeshData(tri.reshape(-1, 3), np.arange(3 * n_faces).reshape(n_faces, 3),
                        np.repeat(np.asarray(m.face_normals, dtype=np.float64), 3, axis=0))

    def transformed(self, x: float, y: float, yaw: float, scale=(1.0, 1.0, 1.0)) -> MeshData:
        """Scaled in the mesh frame, then turned by yaw [rad] and moved to (x, y) [m]."""
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        v = (self.vertices * scale) @ rot.T + [x, y, 0.0]
        n = (self.normals / scale) @ rot.T
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return MeshData(v, self.faces, n)

    def to_trimesh(self) -> trimesh.Trimesh:
        return trimesh.Trimesh(self.vertices, self.faces, vertex_normals=self.normals, process=False)
