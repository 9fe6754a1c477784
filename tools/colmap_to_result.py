#!/usr/bin/env python3
"""Glue between epiloc drive directories and a COLMAP workspace (used by tools/compare_colmap.sh).

Subcommands (python3 standard library only, no numpy):

  links   DRIVE OUTDIR                     symlink a drive's frames as OUTDIR/<frame:010d>.png
  origin  SURVEY                           print the ENU origin used for COLMAP's world frame
  pairs   SURVEY QUERY --db DB --out F     matches_importer pair lists (survey neighbours and
                                           query vs survey frames near the query's GNSS)
  model   SURVEY --db DB --out DIR         the survey's known poses as a COLMAP text model
  result  QUERY --survey SURVEY --model DIR --out F [--fixed-intrinsics DB]
                                           registered query poses -> epiloc result CSV
                                           (optionally re-refined with the prior intrinsics)
  check   MODEL                            reprojection error of the triangulated points
  merge   OUT IN...                        concatenate result CSVs (union of the columns)

World frame of the COLMAP model: local ENU (x east, y north, z up) at the first survey
ground-truth sample, WGS-84. Ground-truth orientations (qw..qz = enu_from_cam in the local ENU
at each sample's own position, camera x right, y down, z forward) are rotated into that ENU;
COLMAP stores cam_from_world (qvec, tvec).
"""

import argparse
import csv
import math
import os
import sqlite3
import sys

# ----------------------------------------------------------------------------- WGS-84

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


def geodetic_to_ecef(lat_deg, lon_deg, alt_m):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    s, c = math.sin(lat), math.cos(lat)
    n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * s * s)
    return ((n + alt_m) * c * math.cos(lon), (n + alt_m) * c * math.sin(lon),
            (n * (1.0 - WGS84_E2) + alt_m) * s)


def ecef_to_geodetic(x, y, z):
    """Exact inverse by fixed-point iteration on the latitude (converges to 1e-15 rad)."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1.0 - WGS84_E2))
    for _ in range(100):
        s = math.sin(lat)
        n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * s * s)
        # h from the exact relation, valid at every latitude.
        h = p * math.cos(lat) + z * s - WGS84_A * math.sqrt(1.0 - WGS84_E2 * s * s)
        new_lat = math.atan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
        done = abs(new_lat - lat) < 1e-15
        lat = new_lat
        if done:
            break
    s = math.sin(lat)
    h = p * math.cos(lat) + z * s - WGS84_A * math.sqrt(1.0 - WGS84_E2 * s * s)
    return math.degrees(lat), math.degrees(lon), h


def enu_from_ecef_rotation(lat_deg, lon_deg):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return [[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]]


class Enu:
    """Local ENU frame at a WGS-84 origin."""

    def __init__(self, lat_deg, lon_deg, alt_m):
        self.origin = (lat_deg, lon_deg, alt_m)
        self.ecef0 = geodetic_to_ecef(lat_deg, lon_deg, alt_m)
        self.r = enu_from_ecef_rotation(lat_deg, lon_deg)

    def forward(self, lat_deg, lon_deg, alt_m):
        e = geodetic_to_ecef(lat_deg, lon_deg, alt_m)
        d = [e[i] - self.ecef0[i] for i in range(3)]
        return mat_vec(self.r, d)

    def reverse(self, enu):
        d = mat_vec(transpose(self.r), enu)
        return ecef_to_geodetic(*[self.ecef0[i] + d[i] for i in range(3)])

    def enu_from_local_enu(self, lat_deg, lon_deg):
        """Rotation taking vectors of the local ENU at (lat, lon) into this ENU."""
        return mat_mul(self.r, transpose(enu_from_ecef_rotation(lat_deg, lon_deg)))


# ----------------------------------------------------------------------------- small linear algebra


def mat_vec(m, v):
    return [m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2] for i in range(3)]


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def transpose(m):
    return [[m[j][i] for j in range(3)] for i in range(3)]


def quat_to_mat(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def mat_to_quat(m):
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        w, x, y, z = 0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = 2.0 * math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2])
        w, x, y, z = (m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s
    elif m[1][1] > m[2][2]:
        s = 2.0 * math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2])
        w, x, y, z = (m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1])
        w, x, y, z = (m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s
    if w < 0:
        w, x, y, z = -w, -x, -y, -z
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


# ----------------------------------------------------------------------------- drives


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def read_frames(drive):
    return [(int(r["frame"]), float(r["timestamp_s"]), r["image"])
            for r in read_csv(os.path.join(drive, "frames.csv"))]


def read_truth_by_frame(drive):
    truth = {}
    for r in read_csv(os.path.join(drive, "ground_truth.csv")):
        if r.get("frame", "") == "":
            continue
        q = (float(r["qw"]), float(r["qx"]), float(r["qy"]), float(r["qz"])) if r["qw"] else None
        truth[int(r["frame"])] = (float(r["lat_deg"]), float(r["lon_deg"]), float(r["alt_m"]), q)
    return truth


def origin_of(survey):
    """First ground-truth sample of the survey drive."""
    r = read_csv(os.path.join(survey, "ground_truth.csv"))[0]
    return Enu(float(r["lat_deg"]), float(r["lon_deg"]), float(r["alt_m"]))


def image_name(prefix, frame):
    return "%s/%010d.png" % (prefix, frame)


def db_images(db):
    con = sqlite3.connect(db)
    rows = con.execute("select image_id, name, camera_id from images").fetchall()
    con.close()
    return {name: (image_id, camera_id) for image_id, name, camera_id in rows}


def db_cameras(db):
    con = sqlite3.connect(db)
    rows = con.execute("select camera_id, model, width, height, params from cameras").fetchall()
    con.close()
    import struct
    cams = {}
    for cid, model, w, h, blob in rows:
        params = struct.unpack("<%dd" % (len(blob) // 8), blob)
        cams[cid] = (model, w, h, params)
    return cams


# ----------------------------------------------------------------------------- subcommands


def cmd_links(a):
    os.makedirs(a.outdir, exist_ok=True)
    names = []
    for frame, _, image in read_frames(a.drive):
        link = os.path.join(a.outdir, "%010d.png" % frame)
        if os.path.lexists(link):
            os.remove(link)
        os.symlink(os.path.abspath(image), link)
        names.append(os.path.join(os.path.basename(a.outdir.rstrip("/")), "%010d.png" % frame))
    if a.list:
        with open(a.list, "w") as f:
            f.write("\n".join(names) + "\n")


def cmd_origin(a):
    print("%.12f,%.12f,%.6f" % origin_of(a.survey).origin)


def interpolate_track(rows, t):
    """Linear interpolation of (t, lat, lon, alt) rows at time t (clamped at the ends)."""
    if t <= rows[0][0]:
        return rows[0][1:]
    if t >= rows[-1][0]:
        return rows[-1][1:]
    lo, hi = 0, len(rows) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if rows[mid][0] <= t:
            lo = mid
        else:
            hi = mid
    u = (t - rows[lo][0]) / (rows[hi][0] - rows[lo][0])
    return tuple(rows[lo][i] + u * (rows[hi][i] - rows[lo][i]) for i in (1, 2, 3))


def cmd_pairs(a):
    enu = origin_of(a.survey)
    survey = read_frames(a.survey)
    truth = read_truth_by_frame(a.survey)
    survey_xy = []
    for frame, _, _ in survey:
        lat, lon, alt, _ = truth[frame]
        survey_xy.append((frame, enu.forward(lat, lon, alt)))
    n_survey = 0
    with open(a.out_survey, "w") as f:
        for i in range(len(survey)):
            for j in range(i + 1, min(len(survey), i + 1 + a.survey_neighbours)):
                f.write("%s %s\n" % (image_name("survey", survey[i][0]), image_name("survey", survey[j][0])))
                n_survey += 1
    # Query prior: the query drive's own GNSS (noisy) at the frame time, never its ground truth.
    gnss = []
    for r in read_csv(os.path.join(a.query, "gnss.csv")):
        gnss.append((float(r["timestamp_s"]), float(r["lat_deg"]), float(r["lon_deg"]), float(r["alt_m"])))
    gnss.sort()
    n_query, per_query = 0, []
    with open(a.out_query, "w") as f:
        for frame, t, _ in read_frames(a.query):
            p = enu.forward(*interpolate_track(gnss, t))
            near = [(math.hypot(x[0] - p[0], x[1] - p[1]), sf) for sf, x in survey_xy]
            chosen = [sf for d, sf in near if d <= a.radius_m]
            if len(chosen) < a.min_candidates:
                chosen = [sf for _, sf in sorted(near)[:a.min_candidates]]
            for sf in chosen:
                f.write("%s %s\n" % (image_name("query", frame), image_name("survey", sf)))
            n_query += len(chosen)
            per_query.append(len(chosen))
    print("pairs: %d survey-survey (each survey frame with its next %d), %d query-survey "
          "(survey frames within %.1f m of the query's GNSS; %d-%d, mean %.1f per query frame)"
          % (n_survey, a.survey_neighbours, n_query, a.radius_m, min(per_query), max(per_query),
             n_query / max(1, len(per_query))))


def read_truth_track(drive):
    """Ground-truth samples sorted by time: (t, lat, lon, alt, quaternion or None)."""
    rows = []
    for r in read_csv(os.path.join(drive, "ground_truth.csv")):
        q = (float(r["qw"]), float(r["qx"]), float(r["qy"]), float(r["qz"])) if r.get("qw") else None
        rows.append((float(r["timestamp_s"]), float(r["lat_deg"]), float(r["lon_deg"]), float(r["alt_m"]), q))
    rows.sort(key=lambda r: r[0])
    return rows


def slerp(q0, q1, u):
    d = sum(a * b for a, b in zip(q0, q1))
    if d < 0:
        q1, d = [-v for v in q1], -d
    if d > 0.9999999:
        q = [a + u * (b - a) for a, b in zip(q0, q1)]
    else:
        th = math.acos(d)
        s0, s1 = math.sin((1 - u) * th) / math.sin(th), math.sin(u * th) / math.sin(th)
        q = [s0 * a + s1 * b for a, b in zip(q0, q1)]
    n = math.sqrt(sum(v * v for v in q))
    return [v / n for v in q]


def survey_poses(survey, enu, at="timestamp"):
    """frame -> (qvec cam_from_world, tvec, centre) in the COLMAP world (= ENU at the origin).

    at="timestamp": the ground truth interpolated at the frame's timestamp (position linear in
    ENU, orientation slerp in the origin's ENU), as `epiloc build-db` positions survey frames;
    at="frame": the ground-truth sample carrying the frame number."""
    track = read_truth_track(survey)
    by_frame = read_truth_by_frame(survey)
    times = [r[0] for r in track]
    poses = {}
    for frame, t, _ in read_frames(survey):
        if at == "frame":
            lat, lon, alt, q = by_frame[frame]
            if q is None:
                raise SystemExit("survey ground truth of frame %d has no orientation" % frame)
            c = enu.forward(lat, lon, alt)
            world_from_cam = mat_mul(enu.enu_from_local_enu(lat, lon), quat_to_mat(*q))
        else:
            import bisect
            k = min(max(bisect.bisect_right(times, t), 1), len(track) - 1)
            a, b = track[k - 1], track[k]
            if not (a[0] - 0.5 <= t <= b[0] + 0.5) or a[4] is None or b[4] is None:
                raise SystemExit("frame %d at t=%.3f: no ground truth pose around it" % (frame, t))
            u = (t - a[0]) / (b[0] - a[0])
            ca, cb = enu.forward(*a[1:4]), enu.forward(*b[1:4])
            c = [ca[i] + u * (cb[i] - ca[i]) for i in range(3)]
            qa = mat_to_quat(mat_mul(enu.enu_from_local_enu(a[1], a[2]), quat_to_mat(*a[4])))
            qb = mat_to_quat(mat_mul(enu.enu_from_local_enu(b[1], b[2]), quat_to_mat(*b[4])))
            world_from_cam = quat_to_mat(*slerp(qa, qb, u))
        cam_from_world = transpose(world_from_cam)
        tv = [-v for v in mat_vec(cam_from_world, c)]
        poses[frame] = (mat_to_quat(cam_from_world), tv, c)
    return poses


def cmd_model(a):
    enu = origin_of(a.survey)
    images = db_images(a.db)
    cams = db_cameras(a.db)
    poses = survey_poses(a.survey, enu, a.survey_poses)
    os.makedirs(a.out, exist_ok=True)
    used_cams = set()
    with open(os.path.join(a.out, "images.txt"), "w") as f:
        f.write("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n# POINTS2D (empty)\n")
        for frame in sorted(poses):
            name = image_name("survey", frame)
            if name not in images:
                raise SystemExit("%s: image %s not in the COLMAP database" % (a.db, name))
            image_id, cam_id = images[name]
            used_cams.add(cam_id)
            q, t, _ = poses[frame]
            f.write("%d %.17g %.17g %.17g %.17g %.17g %.17g %.17g %d %s\n\n"
                    % (image_id, q[0], q[1], q[2], q[3], t[0], t[1], t[2], cam_id, name))
    with open(os.path.join(a.out, "cameras.txt"), "w") as f:
        f.write("# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n")
        for cid in sorted(used_cams):
            model, w, h, params = cams[cid]
            if model != 1:  # PINHOLE
                raise SystemExit("camera %d: expected PINHOLE (model 1), found model %d" % (cid, model))
            f.write("%d PINHOLE %d %d %s\n" % (cid, w, h, " ".join("%.17g" % p for p in params)))
    open(os.path.join(a.out, "points3D.txt"), "w").close()
    print("model: %d survey images with known poses, world = ENU at %.9f,%.9f,%.3f"
          % (len(poses), *enu.origin))


def read_model_images(model):
    """image_id -> (qvec, tvec, camera_id, name, points2D list of (x, y, point3D_id))."""
    images = {}
    with open(os.path.join(model, "images.txt")) as f:
        lines = [l for l in f.read().split("\n") if not l.startswith("#")]
    i = 0
    while i + 1 < len(lines) or (i < len(lines) and lines[i].strip()):
        head = lines[i].split()
        if not head:
            i += 1
            continue
        pts = lines[i + 1].split() if i + 1 < len(lines) else []
        p2d = [(float(pts[k]), float(pts[k + 1]), int(pts[k + 2])) for k in range(0, len(pts) - 2, 3)]
        images[int(head[0])] = ([float(v) for v in head[1:5]], [float(v) for v in head[5:8]],
                                int(head[8]), head[9], p2d)
        i += 2
    return images


def read_model_cameras(model):
    cams = {}
    with open(os.path.join(model, "cameras.txt")) as f:
        for l in f:
            if l.startswith("#") or not l.strip():
                continue
            v = l.split()
            cams[int(v[0])] = (v[1], int(v[2]), int(v[3]), [float(x) for x in v[4:]])
    return cams


def read_model_points(model):
    pts = {}
    with open(os.path.join(model, "points3D.txt")) as f:
        for l in f:
            if l.startswith("#") or not l.strip():
                continue
            v = l.split()
            pts[int(v[0])] = [float(x) for x in v[1:4]]
    return pts


def rodrigues(w):
    th = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    if th < 1e-15:
        return [[1.0, -w[2], w[1]], [w[2], 1.0, -w[0]], [-w[1], w[0], 1.0]]
    k = [v / th for v in w]
    c, s = math.cos(th), math.sin(th)
    kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]]
    kk = mat_mul(kx, kx)
    return [[(1.0 if i == j else 0.0) + s * kx[i][j] + (1 - c) * kk[i][j] for j in range(3)] for i in range(3)]


def solve(a, b):
    """Gaussian elimination with partial pivoting (small dense systems)."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(m[r][col]))
        m[col], m[piv] = m[piv], m[col]
        if abs(m[col][col]) < 1e-300:
            raise ZeroDivisionError("singular system")
        for r in range(col + 1, n):
            f = m[r][col] / m[col][col]
            for c in range(col, n + 1):
                m[r][c] -= f * m[col][c]
    x = [0.0] * n
    for r in range(n - 1, -1, -1):
        x[r] = (m[r][n] - sum(m[r][c] * x[c] for c in range(r + 1, n))) / m[r][r]
    return x


def refine_pose(r, t, obs, intr, iterations=30, cauchy_px=1.0):
    """Pose-only Gauss-Newton (IRLS, Cauchy loss like COLMAP's absolute pose refinement) of
    cam_from_world (r, t) over 2D-3D observations [(x, y, X)] with fixed PINHOLE intrinsics."""
    fx, fy, cx, cy = intr
    for _ in range(iterations):
        h = [[0.0] * 6 for _ in range(6)]
        g = [0.0] * 6
        for x, y, pw in obs:
            pc = [v + t[i] for i, v in enumerate(mat_vec(r, pw))]
            if pc[2] <= 1e-6:
                continue
            iz = 1.0 / pc[2]
            ru, rv = fx * pc[0] * iz + cx - x, fy * pc[1] * iz + cy - y
            wgt = 1.0 / (1.0 + (ru * ru + rv * rv) / (cauchy_px * cauchy_px))
            du = [fx * iz, 0.0, -fx * pc[0] * iz * iz]
            dv = [0.0, fy * iz, -fy * pc[1] * iz * iz]
            # d pc / d(dw) = -[pc]x, d pc / d(dt) = I
            skew = [[0.0, pc[2], -pc[1]], [-pc[2], 0.0, pc[0]], [pc[1], -pc[0], 0.0]]
            ju = [sum(du[k] * skew[k][j] for k in range(3)) for j in range(3)] + du
            jv = [sum(dv[k] * skew[k][j] for k in range(3)) for j in range(3)] + dv
            for i in range(6):
                g[i] += wgt * (ju[i] * ru + jv[i] * rv)
                for j in range(6):
                    h[i][j] += wgt * (ju[i] * ju[j] + jv[i] * jv[j])
        step = solve(h, [-v for v in g])
        dr = rodrigues(step[:3])
        r = mat_mul(dr, r)
        t = [v + step[3 + i] for i, v in enumerate(mat_vec(dr, t))]
        if max(abs(v) for v in step) < 1e-12:
            break
    return r, t


def refine_with_prior_intrinsics(model, images, db):
    """COLMAP 3.8's image_registrator refines the focal length of a camera with the first image
    it registers with it (the CLI cannot switch this off), and later images of that camera use
    that focal length. Re-run the pose-only refinement of every query image over the inlier
    2D-3D correspondences COLMAP kept, with the camera's prior (database) intrinsics."""
    cams = read_model_cameras(model)
    prior = db_cameras(db)
    pts = read_model_points(model)
    out, moved = {}, []
    for image_id, (qv, tv, cid, name, p2d) in images.items():
        if not name.startswith("query/"):
            out[image_id] = (qv, tv, cid, name, p2d)
            continue
        intr = list(prior[cid][3][:4])
        if all(abs(u - v) < 1e-9 for u, v in zip(intr, cams[cid][3][:4])):
            out[image_id] = (qv, tv, cid, name, p2d)
            continue
        obs = [(x, y, pts[pid]) for x, y, pid in p2d if pid >= 0 and pid in pts]
        r0 = quat_to_mat(*qv)
        r, t = refine_pose(r0, tv, obs, intr)
        c0 = mat_vec(transpose(r0), [-v for v in tv])
        c1 = mat_vec(transpose(r), [-v for v in t])
        moved.append(math.sqrt(sum((c0[i] - c1[i]) ** 2 for i in range(3))))
        out[image_id] = (list(mat_to_quat(r)), t, cid, name, p2d)
    if moved:
        moved.sort()
        print("fixed intrinsics: %d query poses re-refined with the prior intrinsics; camera centres "
              "moved median %.4f m, max %.4f m" % (len(moved), moved[len(moved) // 2], moved[-1]))
    return out


def cmd_result(a):
    enu = origin_of(a.survey)
    images = read_model_images(a.model)
    if a.fixed_intrinsics:
        images = refine_with_prior_intrinsics(a.model, images, a.fixed_intrinsics)
    by_name = {v[3]: v for v in images.values()}
    header = ["frame", "timestamp_s", "lat_deg", "lon_deg", "alt_m", "s_m", "db_frame", "method",
              "status", "qw", "qx", "qy", "qz"]
    n_ok = 0
    with open(a.out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        for frame, t, _ in read_frames(a.query):
            img = by_name.get(image_name("query", frame))
            if img is None:
                w.writerow([frame, "%.7f" % t, "", "", "", "", "", a.method, "lost", "", "", "", ""])
                continue
            cam_from_world = quat_to_mat(*img[0])
            world_from_cam = transpose(cam_from_world)
            c = [-v for v in mat_vec(world_from_cam, img[1])]
            lat, lon, alt = enu.reverse(c)
            local_from_world = transpose(enu.enu_from_local_enu(lat, lon))
            q = mat_to_quat(mat_mul(local_from_world, world_from_cam))
            w.writerow([frame, "%.7f" % t, "%.10f" % lat, "%.10f" % lon, "%.4f" % alt, "", "",
                        a.method, "ok", "%.9f" % q[0], "%.9f" % q[1], "%.9f" % q[2], "%.9f" % q[3]])
            n_ok += 1
    print("result: %d of %d query frames registered -> %s" % (n_ok, len(read_frames(a.query)), a.out))


def cmd_check(a):
    """Reprojection check of the model and the camera parameters it ended with."""
    images = read_model_images(a.model)
    cams = read_model_cameras(a.model)
    pts = read_model_points(a.model)
    for cid, (model, w, h, params) in sorted(cams.items()):
        print("camera %d: %s %dx%d %s" % (cid, model, w, h, " ".join("%.4f" % p for p in params)))
    for prefix in ("survey", "query"):
        errs, n_img = [], 0
        for qv, tv, cid, name, p2d in images.values():
            if not name.startswith(prefix + "/"):
                continue
            n_img += 1
            r = quat_to_mat(*qv)
            fx, fy, cx, cy = cams[cid][3][:4]
            for x, y, pid in p2d:
                if pid < 0 or pid not in pts:
                    continue
                pc = [v + tv[i] for i, v in enumerate(mat_vec(r, pts[pid]))]
                if pc[2] <= 0:
                    errs.append(float("inf"))
                    continue
                errs.append(math.hypot(fx * pc[0] / pc[2] + cx - x, fy * pc[1] / pc[2] + cy - y))
        errs.sort()
        if errs:
            print("%s: %d images, %d observations of %d points, reprojection error median %.3f px, "
                  "mean %.3f px, 95%% %.3f px"
                  % (prefix, n_img, len(errs), len(pts), errs[len(errs) // 2],
                     sum(e for e in errs if e != float("inf")) / len(errs), errs[int(0.95 * (len(errs) - 1))]))
        else:
            print("%s: %d images, no observations" % (prefix, n_img))


def cmd_merge(a):
    tables = [read_csv(p) for p in a.inputs]
    header = ["frame", "timestamp_s", "lat_deg", "lon_deg", "alt_m", "s_m", "db_frame", "method", "status"]
    if any(t and "qw" in t[0] for t in tables):  # rows without orientation leave them empty
        header += ["qw", "qx", "qy", "qz"]
    with open(a.out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        for t in tables:
            for r in t:
                w.writerow([r.get(c, "") or "" for c in header])


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("links")
    s.add_argument("drive"), s.add_argument("outdir"), s.add_argument("--list")
    s.set_defaults(fn=cmd_links)
    s = sub.add_parser("origin")
    s.add_argument("survey")
    s.set_defaults(fn=cmd_origin)
    s = sub.add_parser("pairs")
    s.add_argument("survey"), s.add_argument("query")
    s.add_argument("--out-survey", required=True), s.add_argument("--out-query", required=True)
    s.add_argument("--survey-neighbours", type=int, default=4)
    s.add_argument("--radius-m", type=float, default=12.0)
    s.add_argument("--min-candidates", type=int, default=5)
    s.set_defaults(fn=cmd_pairs)
    s = sub.add_parser("model")
    s.add_argument("survey"), s.add_argument("--db", required=True), s.add_argument("--out", required=True)
    s.add_argument("--survey-poses", choices=["timestamp", "frame"], default="timestamp",
                   help="ground truth interpolated at the frame timestamps (as build-db) or the "
                        "sample with the frame number")
    s.set_defaults(fn=cmd_model)
    s = sub.add_parser("result")
    s.add_argument("query"), s.add_argument("--survey", required=True)
    s.add_argument("--model", required=True), s.add_argument("--out", required=True)
    s.add_argument("--method", default="colmap")
    s.add_argument("--fixed-intrinsics", metavar="DATABASE_DB",
                   help="re-refine query poses with the database's prior intrinsics")
    s.set_defaults(fn=cmd_result)
    s = sub.add_parser("check")
    s.add_argument("model")
    s.set_defaults(fn=cmd_check)
    s = sub.add_parser("merge")
    s.add_argument("out"), s.add_argument("inputs", nargs="+")
    s.set_defaults(fn=cmd_merge)
    a = p.parse_args()
    a.fn(a)


if __name__ == "__main__":
    main()
