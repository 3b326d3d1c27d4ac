# mypy: disable-error-code="type-arg,valid-type"
# (the annotations are cyclonedds' IDL markers: sequence[T], array[T, N])
"""The ROS 2 messages dronetrack speaks on DDS, as cyclonedds-python IDL types.

Each class mirrors a ``.msg`` definition field by field, under the DDS type name a
ROS 2 RMW gives it (``formats.ros.names``: ``pkg::msg::dds_::Name``; cyclonedds
writes ``.`` for ``::`` in ``typename``).  They are final structs, which cyclonedds
serialises as XCDR1, the representation ROS 2 uses; the tests check that each one's
bytes equal rosbags' ``serialize_cdr`` of the same message.

The samples themselves are never (de)serialised through these classes: dronetrack
writes the CDR bytes rosbags or its own encoders make and reads the raw bytes into
its numpy decoders (``sources.ros2.dds``).  The classes give the DDS topic its type name
and the type description other XTypes peers match against.

Sources: ros2/common_interfaces (std_msgs, geometry_msgs, sensor_msgs, nav_msgs,
visualization_msgs as of Humble),
ros2/geometry2 (tf2_msgs), ros2/rcl_interfaces (builtin_interfaces),
Livox-SDK/livox_ros_driver2 ``msg/`` and Interbotix/interbotix_ros_core
(interbotix_xs_msgs ``JointGroupCommand``: ``string name``, ``float32[] cmd``).
"""

# No "from __future__ import annotations": cyclonedds reads the annotations as objects.
from dataclasses import dataclass

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint8, uint32, uint64

__all__ = ["IDL_TYPES", "idl_type"]


@dataclass
class Time(IdlStruct, typename="builtin_interfaces.msg.dds_.Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs.msg.dds_.Header_"):
    stamp: Time
    frame_id: str


@dataclass
class String(IdlStruct, typename="std_msgs.msg.dds_.String_"):
    data: str


@dataclass
class PointField(IdlStruct, typename="sensor_msgs.msg.dds_.PointField_"):
    name: str
    offset: uint32
    datatype: uint8
    count: uint32


@dataclass
class PointCloud2(IdlStruct, typename="sensor_msgs.msg.dds_.PointCloud2_"):
    header: Header
    height: uint32
    width: uint32
    fields: sequence[PointField]
    is_bigendian: bool
    point_step: uint32
    row_step: uint32
    data: sequence[uint8]
    is_dense: bool


@dataclass
class CustomPoint(IdlStruct, typename="livox_ros_driver2.msg.dds_.CustomPoint_"):
    offset_time: uint32
    x: float32
    y: float32
    z: float32
    reflectivity: uint8
    tag: uint8
    line: uint8


@dataclass
class CustomMsg(IdlStruct, typename="livox_ros_driver2.msg.dds_.CustomMsg_"):
    header: Header
    timebase: uint64
    point_num: uint32
    lidar_id: uint8
    rsvd: array[uint8, 3]
    points: sequence[CustomPoint]


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs.msg.dds_.Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Point(IdlStruct, typename="geometry_msgs.msg.dds_.Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs.msg.dds_.Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Transform(IdlStruct, typename="geometry_msgs.msg.dds_.Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs.msg.dds_.TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs.msg.dds_.TFMessage_"):
    transforms: sequence[TransformStamped]


@dataclass
class PointStamped(IdlStruct, typename="geometry_msgs.msg.dds_.PointStamped_"):
    header: Header
    point: Point


@dataclass
class Pose(IdlStruct, typename="geometry_msgs.msg.dds_.Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs.msg.dds_.PoseStamped_"):
    header: Header
    pose: Pose


@dataclass
class Path(IdlStruct, typename="nav_msgs.msg.dds_.Path_"):
    header: Header
    poses: sequence[PoseStamped]


@dataclass
class JointState(IdlStruct, typename="sensor_msgs.msg.dds_.JointState_"):
    header: Header
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@dataclass
class JointGroupCommand(IdlStruct, typename="interbotix_xs_msgs.msg.dds_.JointGroupCommand_"):
    name: str
    cmd: sequence[float32]


@dataclass
class Duration(IdlStruct, typename="builtin_interfaces.msg.dds_.Duration_"):
    sec: int32
    nanosec: uint32


@dataclass
class ColorRGBA(IdlStruct, typename="std_msgs.msg.dds_.ColorRGBA_"):
    r: float32
    g: float32
    b: float32
    a: float32


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs.msg.dds_.CompressedImage_"):
    header: Header
    format: str
    data: sequence[uint8]


@dataclass
class UVCoordinate(IdlStruct, typename="visualization_msgs.msg.dds_.UVCoordinate_"):
    u: float32
    v: float32


@dataclass
class MeshFile(IdlStruct, typename="visualization_msgs.msg.dds_.MeshFile_"):
    filename: str
    data: sequence[uint8]


@dataclass
class Marker(IdlStruct, typename="visualization_msgs.msg.dds_.Marker_"):
    header: Header
    ns: str
    id: int32
    type: int32
    action: int32
    pose: Pose
    scale: Vector3
    color: ColorRGBA
    lifetime: Duration
    frame_locked: bool
    points: sequence[Point]
    colors: sequence[ColorRGBA]
    texture_resource: str
    texture: CompressedImage
    uv_coordinates: sequence[UVCoordinate]
    text: str
    mesh_resource: str
    mesh_file: MeshFile
    mesh_use_embedded_materials: bool


@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs.msg.dds_.MarkerArray_"):
    markers: sequence[Marker]


IDL_TYPES: dict[str, type[IdlStruct]] = {
    "std_msgs/msg/String": String,
    "sensor_msgs/msg/PointCloud2": PointCloud2,
    "livox_ros_driver2/msg/CustomMsg": CustomMsg,
    "tf2_msgs/msg/TFMessage": TFMessage,
    "geometry_msgs/msg/PointStamped": PointStamped,
    "geometry_msgs/msg/PoseStamped": PoseStamped,
    "nav_msgs/msg/Path": Path,
    "sensor_msgs/msg/JointState": JointState,
    "interbotix_xs_msgs/msg/JointGroupCommand": JointGroupCommand,
    "visualization_msgs/msg/MarkerArray": MarkerArray,
}


def idl_type(msg_type: str) -> type[IdlStruct]:
    """The IDL class of ROS 2 message type ``msg_type`` (KeyError if there is none)."""
    return IDL_TYPES[msg_type]
