#!/usr/bin/env python3
"""Writes the small ROS 1 bags of the hmap::ros tests with ROS's own writer (Debian python3-rosbag),
from the first real Ouster OS0-64 scans of ../shared/data/balm_os0 (every STEP-th point).

usage: make_test_bags.py DATA_DIR OUT_DIR [SCANS] [STEP]
       make_test_bags.py DATA_DIR --full OUT.bag   (all 80 full scans, /os_cloud + /tf + /odom, lz4)
       make_test_bags.py --layout BAG   (JSON, from rosbag's own index: where each message of BAG
                                         becomes whole in the file, and where its chunks lie)

Bags written to OUT_DIR (stamps = balm_os0/times.txt; poses = balm_os0/poses.txt, P_k):
  tf.bag          /os_cloud (x y z intensity float32, frame os_sensor); /tf_static map->odom
                  (translation 1 2 0); /tf odom->os_sensor at t_k -+ 0.1 s with P_k's rotation and
                  P_k's translation -+ (0.1, 0, 0), so interpolation at t_k gives exactly P_k
  tf_lz4.bag, tf_bz2.bag   the same, chunks compressed with lz4 / bz2
  odom.bag        /os_cloud + /odom nav_msgs/Odometry (odom <- os_sensor) = P_k at t_k
  layout.bag      /cloud: scan 0 as a big-endian cloud with fields z, pad, x (float64), y in that
                  order, then scan 1 organized (height 4) with every 7th point NaN and 8 bytes of
                  row padding; /odom as in odom.bag
  nopose.bag      /os_cloud at t_k, /odom only 10 s after the last cloud
  tiny.bag        one 20-point cloud and one odometry message (for the damaged-file tests)
  imu.bag         /os_cloud with a uint32 field t (ns, 0..99 ms over each cloud's points), /odom as
                  in odom.bag, /imu sensor_msgs/Imu at 100 Hz from t_0 - 0.1 s: gyro (0.01 k,
                  -0.02, 0.3), accel (0, 0, 9.81), orientation covariance[0] = -1 (none)
  imu_two.bag     /imu and /imu_b (two Imu topics), one message each
  two_clouds.bag  /os_cloud and /os_cloud_b (the same clouds), /odom as in odom.bag
  chunked.bag, chunked_bz2.bag, chunked_lz4.bag   per scan k: /tf odom->os_sensor at t_k - 0.1 s,
                  /odom, /os_cloud at t_k, /tf at t_k + 0.1 s; chunks of about 8 kB (one per scan),
                  uncompressed / bz2 / lz4 (cut at chosen bytes by the tests of bags cut off)
  killed.bag, killed_lz4.bag   as chunked(_lz4).bag, the writer killed (os._exit after a flush)
                  after the second scan's cloud, before it closed the chunk or wrote the index;
                  killed*.bag.expected: how many messages its closed chunks hold (and, stored
                  uncompressed, the open chunk's whole ones), by the writer's own counts
"""
import os
import sys

import math
import struct
import rosbag
import rospy
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, PointCloud2, PointField
from tf2_msgs.msg import TFMessage


def rotation_to_quaternion(r):
    # Shepperd's method; r is a proper rotation
    w = math.sqrt(max(0.0, 1.0 + r[0][0] + r[1][1] + r[2][2])) / 2.0
    x = math.sqrt(max(0.0, 1.0 + r[0][0] - r[1][1] - r[2][2])) / 2.0
    y = math.sqrt(max(0.0, 1.0 - r[0][0] + r[1][1] - r[2][2])) / 2.0
    z = math.sqrt(max(0.0, 1.0 - r[0][0] - r[1][1] + r[2][2])) / 2.0
    x = math.copysign(x, r[2][1] - r[1][2])
    y = math.copysign(y, r[0][2] - r[2][0])
    z = math.copysign(z, r[1][0] - r[0][1])
    return x, y, z, w


def cloud_msg(points, stamp, frame, big_endian=False, odd_layout=False, organized_rows=0):
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = frame
    n = len(points)
    order = '>' if big_endian else '<'
    if odd_layout:
        # z float32 @0, 4 bytes padding, x float64 @8, y float32 @16; point_step 24
        fields = [PointField('z', 0, PointField.FLOAT32, 1), PointField('x', 8, PointField.FLOAT64, 1),
                  PointField('y', 16, PointField.FLOAT32, 1)]
        step = 24
        pack = lambda p: struct.pack(order + 'f4xdf4x', p[2], p[0], p[1])
    else:
        fields = [PointField(name, 4 * i, PointField.FLOAT32, 1) for i, name in enumerate(['x', 'y', 'z', 'intensity'])]
        step = 16
        pack = lambda p: struct.pack(order + 'ffff', p[0], p[1], p[2], p[3])
    msg.fields = fields
    msg.is_bigendian = big_endian
    msg.point_step = step
    msg.is_dense = True
    if organized_rows:
        width = n // organized_rows
        row_pad = 8
        msg.height = organized_rows
        msg.width = width
        msg.row_step = width * step + row_pad
        msg.data = b''.join(b''.join(pack(points[r * width + c]) for c in range(width)) + b'\xab' * row_pad
                            for r in range(organized_rows))
        msg.is_dense = False
    else:
        msg.height = 1
        msg.width = n
        msg.row_step = n * step
        msg.data = b''.join(pack(p) for p in points)
    return msg


def transform(parent, child, stamp, rot, trans):
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = (float(v) for v in trans)
    q = rotation_to_quaternion(rot)
    t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w = (float(v) for v in q)
    return t


def odometry(stamp, rot, trans):
    o = Odometry()
    o.header.stamp = stamp
    o.header.frame_id = 'odom'
    o.child_frame_id = 'os_sensor'
    o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z = (float(v) for v in trans)
    q = rotation_to_quaternion(rot)
    o.pose.pose.orientation.x, o.pose.pose.orientation.y, o.pose.pose.orientation.z, o.pose.pose.orientation.w = (float(v) for v in q)
    return o


def full_bag(data_dir, out):
    poses = []
    with open(f'{data_dir}/balm_os0/poses.txt') as f:
        for line in f:
            v = [float(x) for x in line.split()]
            if len(v) == 12:
                poses.append(([v[0:3], v[4:7], v[8:11]], [v[3], v[7], v[11]]))
    with open(f'{data_dir}/balm_os0/times.txt') as f:
        times = [float(line) for line in f if line.strip()]
    # The folder is made (a fresh clone has no out/bag), and the bag written under a temporary
    # name and renamed: an interrupted run leaves no torn bag under the name.
    os.makedirs(os.path.dirname(out) or '.', exist_ok=True)
    partial = out + '.partial'
    with rosbag.Bag(partial, 'w', compression='lz4') as bag:
        for k, (rot, trans) in enumerate(poses):
            stamp = rospy.Time.from_sec(times[k])
            bag.write('/odom', odometry(stamp, rot, trans), stamp)
            bag.write('/tf', TFMessage([transform('odom', 'os_sensor', stamp, rot, trans)]), stamp)
            with open(f'{data_dir}/balm_os0/velodyne/{k:06d}.bin', 'rb') as f:
                raw = f.read()
            msg = PointCloud2()
            msg.header.stamp = stamp
            msg.header.frame_id = 'os_sensor'
            msg.height, msg.width = 1, len(raw) // 16
            msg.fields = [PointField(name, 4 * i, PointField.FLOAT32, 1) for i, name in enumerate(['x', 'y', 'z', 'intensity'])]
            msg.is_bigendian, msg.point_step, msg.row_step, msg.data, msg.is_dense = False, 16, len(raw), raw, True
            bag.write('/os_cloud', msg, stamp)
    os.replace(partial, out)


def layout(path):
    """Prints, from rosbag's own index of an indexed bag, the byte where each message becomes
    whole (an uncompressed chunk: its record's end; a compressed one: the chunk's end) and the chunks."""
    import json
    with rosbag.Bag(path) as bag:
        f = bag._file
        chunks = []
        for info in bag._chunks:
            h = bag._chunk_headers[info.pos]
            chunks.append({'pos': info.pos, 'data_pos': h.data_pos, 'end': h.data_pos + h.compressed_size,
                           'compression': h.compression})
        messages = []
        for conn_id, entries in bag._connection_indexes.items():
            topic = bag._connections[conn_id].topic
            for e in entries:
                h = bag._chunk_headers[e.chunk_pos]
                if h.compression != 'none':
                    messages.append({'topic': topic, 'whole_at': h.data_pos + h.compressed_size})
                    continue
                f.seek(h.data_pos + e.offset)
                while True:  # the entry may point at the connection record before the message
                    header = rosbag.bag._read_header(f)
                    size = rosbag.bag._read_uint32(f)
                    f.seek(size, os.SEEK_CUR)
                    if rosbag.bag._read_uint8_field(header, 'op') == 0x02:
                        break
                messages.append({'topic': topic, 'whole_at': f.tell()})
        print(json.dumps({'size': os.path.getsize(path), 'chunks': chunks, 'messages': messages}))


def main():
    if len(sys.argv) == 3 and sys.argv[1] == '--layout':
        layout(sys.argv[2])
        return
    if len(sys.argv) == 4 and sys.argv[2] == '--full':
        full_bag(sys.argv[1], sys.argv[3])
        return
    data_dir, out_dir = sys.argv[1], sys.argv[2]
    os.makedirs(out_dir, exist_ok=True)
    scans = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    step = int(sys.argv[4]) if len(sys.argv) > 4 else 10
    poses = []  # (rotation rows, translation)
    with open(f'{data_dir}/balm_os0/poses.txt') as f:
        for line in f:
            v = [float(x) for x in line.split()]
            if len(v) == 12:
                poses.append(([v[0:3], v[4:7], v[8:11]], [v[3], v[7], v[11]]))
    with open(f'{data_dir}/balm_os0/times.txt') as f:
        times = [float(line) for line in f if line.strip()]
    clouds = []
    for k in range(scans):
        with open(f'{data_dir}/balm_os0/velodyne/{k:06d}.bin', 'rb') as f:
            raw = f.read()
        points = list(struct.iter_unpack('<ffff', raw))
        clouds.append([list(p) for p in points[::step]])
    stamps = [rospy.Time.from_sec(float(times[k])) for k in range(scans)]

    def write_clouds(bag, topic='/os_cloud'):
        for k in range(scans):
            bag.write(topic, cloud_msg(clouds[k], stamps[k], 'os_sensor'), stamps[k])

    for name, compression in (('tf', 'none'), ('tf_lz4', 'lz4'), ('tf_bz2', 'bz2')):
        with rosbag.Bag(f'{out_dir}/{name}.bag', 'w', compression=compression) as bag:
            static = TFMessage([transform('map', 'odom', stamps[0], [[1, 0, 0], [0, 1, 0], [0, 0, 1]], (1.0, 2.0, 0.0))])
            bag.write('/tf_static', static, stamps[0])
            for k in range(scans):
                for dt in (-0.1, 0.1):
                    t = rospy.Time.from_sec(float(times[k]) + dt)
                    trans = [poses[k][1][0] + dt, poses[k][1][1], poses[k][1][2]]
                    bag.write('/tf', TFMessage([transform('odom', 'os_sensor', t, poses[k][0], trans)]), t)
            write_clouds(bag)

    with rosbag.Bag(f'{out_dir}/odom.bag', 'w', compression='lz4') as bag:
        for k in range(scans):
            bag.write('/odom', odometry(stamps[k], poses[k][0], poses[k][1]), stamps[k])
        write_clouds(bag)

    with rosbag.Bag(f'{out_dir}/layout.bag', 'w') as bag:
        for k in range(2):
            bag.write('/odom', odometry(stamps[k], poses[k][0], poses[k][1]), stamps[k])
        bag.write('/cloud', cloud_msg(clouds[0], stamps[0], 'os_sensor', big_endian=True, odd_layout=True), stamps[0])
        organized = [list(p) for p in clouds[1]]
        for p in organized[::7]:
            p[0] = p[1] = p[2] = float('nan')
        bag.write('/cloud', cloud_msg(organized, stamps[1], 'os_sensor', organized_rows=4), stamps[1])

    with rosbag.Bag(f'{out_dir}/nopose.bag', 'w') as bag:
        late = rospy.Time.from_sec(float(times[scans - 1]) + 10.0)
        bag.write('/odom', odometry(late, poses[0][0], poses[0][1]), late)
        write_clouds(bag)

    def imu_msg(t, k):
        m = Imu()
        m.header.stamp = t
        m.header.frame_id = 'os_imu'
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = 0.01 * k, -0.02, 0.3
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = 0.0, 0.0, 9.81
        m.orientation_covariance[0] = -1.0
        return m

    with rosbag.Bag(f'{out_dir}/imu.bag', 'w') as bag:
        for k in range(scans):
            bag.write('/odom', odometry(stamps[k], poses[k][0], poses[k][1]), stamps[k])
            pts = clouds[k]
            msg = PointCloud2()
            msg.header.stamp = stamps[k]
            msg.header.frame_id = 'os_sensor'
            msg.height, msg.width = 1, len(pts)
            msg.fields = [PointField(name, 4 * i, PointField.FLOAT32, 1) for i, name in enumerate(['x', 'y', 'z'])]
            msg.fields.append(PointField('t', 12, PointField.UINT32, 1))
            msg.is_bigendian, msg.point_step, msg.row_step, msg.is_dense = False, 16, 16 * len(pts), True
            n = len(pts)
            msg.data = b''.join(struct.pack('<fffI', p[0], p[1], p[2], (99000000 * i) // max(1, n - 1))
                                for i, p in enumerate(pts))
            bag.write('/os_cloud', msg, stamps[k])
        t0 = float(times[0]) - 0.1
        count = int((float(times[scans - 1]) - t0) * 100) + 10
        for k in range(count):
            t = rospy.Time.from_sec(t0 + 0.01 * k)
            bag.write('/imu', imu_msg(t, k), t)

    with rosbag.Bag(f'{out_dir}/imu_two.bag', 'w') as bag:
        bag.write('/imu', imu_msg(stamps[0], 0), stamps[0])
        bag.write('/imu_b', imu_msg(stamps[0], 1), stamps[0])

    with rosbag.Bag(f'{out_dir}/two_clouds.bag', 'w') as bag:
        write_clouds(bag)
        write_clouds(bag, '/os_cloud_b')
        for k in range(scans):
            bag.write('/odom', odometry(stamps[k], poses[k][0], poses[k][1]), stamps[k])

    def write_scan(bag, k):
        before = rospy.Time.from_sec(float(times[k]) - 0.1)
        after = rospy.Time.from_sec(float(times[k]) + 0.1)
        bag.write('/tf', TFMessage([transform('odom', 'os_sensor', before, poses[k][0], poses[k][1])]), before)
        bag.write('/odom', odometry(stamps[k], poses[k][0], poses[k][1]), stamps[k])
        bag.write('/os_cloud', cloud_msg(clouds[k], stamps[k], 'os_sensor'), stamps[k])
        bag.write('/tf', TFMessage([transform('odom', 'os_sensor', after, poses[k][0], poses[k][1])]), after)

    for name, compression in (('chunked', 'none'), ('chunked_bz2', 'bz2'), ('chunked_lz4', 'lz4')):
        with rosbag.Bag(f'{out_dir}/{name}.bag', 'w', compression=compression, chunk_threshold=8192) as bag:
            for k in range(scans):
                write_scan(bag, k)

    for name, compression in (('killed', 'none'), ('killed_lz4', 'lz4')):
        pid = os.fork()
        if pid == 0:
            bag = rosbag.Bag(f'{out_dir}/{name}.bag', 'w', compression=compression, chunk_threshold=8192)
            for k in range(min(2, scans)):
                write_scan(bag, k)
            closed = sum(sum(c.connection_counts.values()) for c in bag._chunks)
            open_chunk = sum(bag._curr_chunk_info.connection_counts.values()) if bag._curr_chunk_info else 0
            with open(f'{out_dir}/{name}.bag.expected', 'w') as f:
                f.write(str(closed + (open_chunk if compression == 'none' else 0)))
            bag._file.flush()
            os._exit(0)  # as a recorder killed: nothing closed, no index
        os.waitpid(pid, 0)

    with rosbag.Bag(f'{out_dir}/tiny.bag', 'w') as bag:
        bag.write('/odom', odometry(stamps[0], poses[0][0], poses[0][1]), stamps[0])
        bag.write('/os_cloud', cloud_msg(clouds[0][:20], stamps[0], 'os_sensor'), stamps[0])


if __name__ == '__main__':
    main()
