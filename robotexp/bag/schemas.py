"""ROS 2 message definitions (the `ros2msg` text of MCAP schemas) of the messages a recording holds.

Each schema is the message's own definition followed by every message it uses, each after a line of
80 `=` and `MSG: package/Type`, as rosbag2 writes them (the definitions are those of ROS 2 Humble's
common_interfaces; `builtin_interfaces/Time` and `Duration` are primitives to the MCAP ROS 2 codec).
"""

from __future__ import annotations

__all__ = ["SCHEMAS", "LASER_SCAN", "ODOMETRY", "TF_MESSAGE", "OCCUPANCY_GRID", "EXACT_SCAN", "MARKER_ARRAY"]

_SEP = "=" * 80

_HEADER = """builtin_interfaces/Time stamp
string frame_id"""
_POINT = """float64 x
float64 y
float64 z"""
_QUATERNION = """float64 x 0
float64 y 0
float64 z 0
float64 w 1"""
_VECTOR3 = """float64 x
float64 y
float64 z"""
_POSE = """Point position
Quaternion orientation"""
_TWIST = """Vector3  linear
Vector3  angular"""
_TRANSFORM = """Vector3 translation
Quaternion rotation"""

_DEPS = {
    "std_msgs/Header": _HEADER,
    "geometry_msgs/Point": _POINT,
    "geometry_msgs/Quaternion": _QUATERNION,
    "geometry_msgs/Vector3": _VECTOR3,
    "geometry_msgs/Pose": _POSE,
    "geometry_msgs/Twist": _TWIST,
    "geometry_msgs/Transform": _TRANSFORM,
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\nTransform transform",
    "std_msgs/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a",
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "visualization_msgs/UVCoordinate": "float64 u\nfloat64 v",
    "visualization_msgs/MeshFile": "string filename\nuint8[] data",
    "visualization_msgs/Marker": """int32 ARROW=0
int32 CUBE=1
int32 SPHERE=2
int32 CYLINDER=3
int32 LINE_STRIP=4
int32 LINE_LIST=5
int32 CUBE_LIST=6
int32 SPHERE_LIST=7
int32 POINTS=8
int32 TEXT_VIEW_FACING=9
int32 MESH_RESOURCE=10
int32 TRIANGLE_LIST=11
int32 ADD=0
int32 MODIFY=0
int32 DELETE=2
int32 DELETEALL=3
std_msgs/Header header
string ns
int32 id
int32 type
int32 action
geometry_msgs/Pose pose
geometry_msgs/Vector3 scale
std_msgs/ColorRGBA color
builtin_interfaces/Duration lifetime
bool frame_locked
geometry_msgs/Point[] points
std_msgs/ColorRGBA[] colors
string texture_resource
sensor_msgs/CompressedImage texture
UVCoordinate[] uv_coordinates
string text
string mesh_resource
MeshFile mesh_file
bool mesh_use_embedded_materials""",
    "nav_msgs/MapMetaData": ("builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\n"
                             "uint32 height\ngeometry_msgs/Pose origin"),
}


def _schema(main: str, deps: tuple[str, ...]) -> str:
    """`main` followed by the definitions of `deps`."""
    parts = [main]
    for name in deps:
        parts.append(f"{_SEP}\nMSG: {name}\n{_DEPS[name]}")
    return "\n".join(parts)


LASER_SCAN = ("sensor_msgs/msg/LaserScan", _schema(
    """std_msgs/Header header
float32 angle_min
float32 angle_max
float32 angle_increment
float32 time_increment
float32 scan_time
float32 range_min
float32 range_max
float32[] ranges
float32[] intensities""", ("std_msgs/Header",)))

ODOMETRY = ("nav_msgs/msg/Odometry", _schema(
    """std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist""",
    ("std_msgs/Header", "geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose", "geometry_msgs/Point",
     "geometry_msgs/Quaternion", "geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist",
     "geometry_msgs/Vector3")))

TF_MESSAGE = ("tf2_msgs/msg/TFMessage", _schema(
    "geometry_msgs/TransformStamped[] transforms",
    ("geometry_msgs/TransformStamped", "std_msgs/Header", "geometry_msgs/Transform", "geometry_msgs/Vector3",
     "geometry_msgs/Quaternion")))

OCCUPANCY_GRID = ("nav_msgs/msg/OccupancyGrid", _schema(
    """std_msgs/Header header
MapMetaData info
int8[] data""",
    ("std_msgs/Header", "nav_msgs/MapMetaData", "geometry_msgs/Pose", "geometry_msgs/Point",
     "geometry_msgs/Quaternion")))

# robotexp's own: the scan exactly as the map integrated it (LaserScan's float32 fields round the beam
# angles and ranges: a replay from them may differ from the run in a few cells)
EXACT_SCAN = ("robotexp_msgs/msg/ExactScan", _schema(
    """std_msgs/Header header
float64 angle_min
float64 angle_increment
float64[] angles
float64[] ranges
float64 range_max
float64 offset_x""", ("std_msgs/Header",)))

# visualization_msgs/MarkerArray as ROS 2 Humble defines it (Marker with its texture and mesh fields)
MARKER_ARRAY = ("visualization_msgs/msg/MarkerArray", _schema(
    "Marker[] markers",
    ("visualization_msgs/Marker", "std_msgs/Header", "geometry_msgs/Pose", "geometry_msgs/Point",
     "geometry_msgs/Quaternion", "geometry_msgs/Vector3", "std_msgs/ColorRGBA",
     "sensor_msgs/CompressedImage", "visualization_msgs/UVCoordinate", "visualization_msgs/MeshFile")))

SCHEMAS = {name: text for name, text in (LASER_SCAN, ODOMETRY, TF_MESSAGE, OCCUPANCY_GRID, EXACT_SCAN,
                                         MARKER_ARRAY)}
