// troupe's picture of people: a perspective camera, the floor grid and t2m-22 skeletons on a 2-D
// canvas. Shared, word for word, by the HTML player (src/viewer/player.html inlines it) and the
// web page (web/, which loads it as a file), so that both draw the same thing; the arithmetic is
// Camera::to_camera / project_camera's in src/viewer/camera.rs.
"use strict";
const TroupeDraw = (function () {
  const NEAR = 0.05;           // metres: nearer points are not drawn (Camera::NEAR_M)
  const BACKGROUND = "#f4f4f2";
  const GRID = "#cfcfcf";
  const BONE_PX = 3, JOINT_PX = 3.5, HEAD_M = 0.1;

  // The camera's eye and axes from its orbit (degrees, metres).
  function basis(c) {
    const y = (c.yaw * Math.PI) / 180, p = (c.pitch * Math.PI) / 180;
    const back = [Math.cos(p) * Math.sin(y), Math.sin(p), Math.cos(p) * Math.cos(y)];
    const eye = [0, 1, 2].map((d) => c.target[d] + c.distance * back[d]);
    const f = back.map((v) => -v);
    const r = [Math.cos(y), 0, -Math.sin(y)];
    const u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
    return { eye, r, u, f };
  }
  function toCamera(b, x, y, z) {
    const dx = x - b.eye[0], dy = y - b.eye[1], dz = z - b.eye[2];
    return [
      dx * b.r[0] + dy * b.r[1] + dz * b.r[2],
      dx * b.u[0] + dy * b.u[1] + dz * b.u[2],
      dx * b.f[0] + dy * b.f[1] + dz * b.f[2],
    ];
  }

  // One picture on `ctx` (W × H CSS pixels): the background, the floor grid of `stage`
  // ({floor, grid: [x0, x1, z0, z1, step], parents, head}) and each of `bodies`
  // ({colour, pos, base}: the joints' world positions are pos[base .. base + 3 × joints]),
  // farthest first.
  function draw(ctx, W, H, cam, stage, bodies) {
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, W, H);
    const b = basis(cam);
    const focal = (0.5 * Math.min(W, H)) / Math.tan((cam.fov * Math.PI) / 360);
    const screen = (c) => [W / 2 + (focal * c[0]) / c[2], H / 2 - (focal * c[1]) / c[2]];
    // A segment between camera-space points, cut at the near plane.
    const segment = (a, c) => {
      if (a[2] < NEAR && c[2] < NEAR) return;
      const cut = (from, to) => {
        const s = (NEAR - from[2]) / (to[2] - from[2]);
        return [0, 1, 2].map((d) => from[d] + s * (to[d] - from[d]));
      };
      if (a[2] < NEAR) a = cut(a, c);
      else if (c[2] < NEAR) c = cut(c, a);
      const p = screen(a), q = screen(c);
      ctx.moveTo(p[0], p[1]);
      ctx.lineTo(q[0], q[1]);
    };

    const [x0, x1, z0, z1, step] = stage.grid;
    ctx.strokeStyle = GRID;
    ctx.lineWidth = 1;
    ctx.beginPath();
    for (let x = x0; x <= x1 + 1e-6; x += step) {
      segment(toCamera(b, x, stage.floor, z0), toCamera(b, x, stage.floor, z1));
    }
    for (let z = z0; z <= z1 + 1e-6; z += step) {
      segment(toCamera(b, x0, stage.floor, z), toCamera(b, x1, stage.floor, z));
    }
    ctx.stroke();

    const posed = bodies.map((body) => {
      const joints = [];
      let depth = 0;
      for (let j = 0; j < stage.parents.length; j++) {
        const o = body.base + j * 3;
        const c = toCamera(b, body.pos[o], body.pos[o + 1], body.pos[o + 2]);
        joints.push(c);
        depth += c[2];
      }
      return { body, joints, depth };
    });
    posed.sort((a, c) => c.depth - a.depth);
    ctx.lineCap = "round";
    ctx.lineJoin = "round";
    for (const { body, joints } of posed) {
      ctx.strokeStyle = body.colour;
      ctx.fillStyle = body.colour;
      ctx.lineWidth = BONE_PX;
      ctx.beginPath();
      stage.parents.forEach((parent, j) => {
        if (parent >= 0) segment(joints[parent], joints[j]);
      });
      ctx.stroke();
      joints.forEach((c, j) => {
        if (c[2] < NEAR) return;
        const s = screen(c);
        const radius = j === stage.head ? Math.max(JOINT_PX + 1, (HEAD_M * focal) / c[2]) : JOINT_PX;
        ctx.beginPath();
        ctx.arc(s[0], s[1], radius, 0, 2 * Math.PI);
        ctx.fill();
      });
    }
  }

  return { NEAR, basis, toCamera, draw };
})();
