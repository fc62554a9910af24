"""What every gnss_sim lifecycle node shares: parameters from the one table,
validation on configure, diagnostics, time stamps.

The pattern follows ros2/demos lifecycle_py: resources are made in
``on_configure`` and freed in ``on_cleanup``; publishers are lifecycle
publishers, active only between ``on_activate`` and ``on_deactivate``.
"""
from __future__ import annotations

import functools
import gc
import os
import warnings

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.parameter import Parameter

from gnss_sim_ros2.core.time import GnssTime, gnss_to_ros_time, ros_time_to_gnss
from gnss_sim_ros2.parameters import NODE_NAMES, params_of, validate_node

_KIND_TYPES = {
    "bool": (ParameterType.PARAMETER_BOOL, Parameter.Type.BOOL),
    "integer": (ParameterType.PARAMETER_INTEGER, Parameter.Type.INTEGER),
    "double": (ParameterType.PARAMETER_DOUBLE, Parameter.Type.DOUBLE),
    "string": (ParameterType.PARAMETER_STRING, Parameter.Type.STRING),
    "string_array": (ParameterType.PARAMETER_STRING_ARRAY, Parameter.Type.STRING_ARRAY),
    "double_array": (ParameterType.PARAMETER_DOUBLE_ARRAY, Parameter.Type.DOUBLE_ARRAY),
}


#: the gnss_sim nodes whose callbacks run (innermost last): a Python warning raised there goes to its logger
_SPEAKING: list = []
_PREVIOUS_SHOWWARNING = None


def _node_warning(message, category, filename, lineno, file=None, line=None):
    """warnings.showwarning in a process with gnss_sim nodes: one line through the logger of the node whose
    callback raised it (gnss_sim's own warnings name their file and reason; another package's say where they
    come from); outside a node's callback, what showed warnings before (gnss-sim's one-line logging), or the
    ``gnss_sim`` ROS logger in a node executable."""
    text = " ".join(str(message).split())
    if not (getattr(category, "__module__", "") or "").startswith("gnss_sim_ros2"):
        text = f"{category.__name__} ({os.path.basename(str(filename))}:{lineno}): {text}"
    if _SPEAKING:
        _SPEAKING[-1].get_logger().warning(text)
    elif _PREVIOUS_SHOWWARNING not in (None, getattr(warnings, "_showwarning_orig", None)):
        _PREVIOUS_SHOWWARNING(message, category, filename, lineno, file, line)
    else:
        from rclpy.logging import get_logger

        get_logger("gnss_sim").warning(text)


def _route_warnings_to_nodes() -> None:
    global _PREVIOUS_SHOWWARNING
    if warnings.showwarning is not _node_warning:
        _PREVIOUS_SHOWWARNING = warnings.showwarning
        warnings.showwarning = _node_warning


class GnssSimNode(LifecycleNode):
    """Base of the gnss_sim lifecycle nodes.

    Subclasses set ``PARAMS_KEY`` (a key of ``parameters.NODE_NAMES``) and
    implement ``configure(params)`` / ``cleanup()`` / ``activate()`` /
    ``deactivate()``; a ``ValueError`` from ``configure`` makes the transition
    fail with the message logged (the node stays unconfigured).
    """

    PARAMS_KEY = ""

    def __init__(self, node_name: str | None = None, **kwargs):
        super().__init__(node_name or NODE_NAMES[self.PARAMS_KEY], **kwargs)
        _route_warnings_to_nodes()         # warnings of this node's callbacks: its logger, one line each
        self.params: dict = {}
        self.last_error = ""
        self._owned_publishers: list = []  # made in configure, destroyed after cleanup()
        self._owned_active: list = []      # timers and subscriptions made in activate, destroyed after deactivate()
        self._jump_handles: list = []      # clock jump callbacks of active_clock_timer
        for p in params_of(self.PARAMS_KEY):
            ros_type, py_type = _KIND_TYPES[p.kind]
            desc = ParameterDescriptor(name=p.name, type=ros_type, description=p.description)
            if p.choices:
                desc.additional_constraints = "one of: " + ", ".join(map(str, p.choices))
            if p.kind == "double" and (p.min is not None or p.max is not None):
                desc.floating_point_range = [FloatingPointRange(
                    from_value=float(p.min if p.min is not None else -1e300),
                    to_value=float(p.max if p.max is not None else 1e300), step=0.0)]
            if p.kind == "integer" and (p.min is not None or p.max is not None):
                desc.integer_range = [IntegerRange(
                    from_value=int(p.min if p.min is not None else -(2**62)),
                    to_value=int(p.max if p.max is not None else 2**62), step=0)]
            if isinstance(p.default, list) and not p.default:
                self.declare_parameter(p.name, py_type, desc)
            else:
                try:
                    self.declare_parameter(p.name, p.default, desc)
                except Exception as exc:  # a range violation from the parameter file
                    # declare without the range so that configure reports it clearly
                    self.last_error = f"{self.get_name()}: parameter '{p.name}': {exc}"
                    desc.floating_point_range = []
                    desc.integer_range = []
                    self.declare_parameter(p.name, p.default, desc)

    # ----------------------------------------------------------- owned entities
    def speaking(self, callback):
        """``callback`` with this node as the one whose logger takes the warnings it raises (its signature kept:
        rclpy reads it to choose what it passes, e.g. a timer's TimerInfo)."""
        @functools.wraps(callback)
        def run(*args, **kwargs):
            _SPEAKING.append(self)
            try:
                return callback(*args, **kwargs)
            finally:
                _SPEAKING.pop()
        return run

    def lifecycle_publisher(self, msg_type, topic: str, qos):
        """A lifecycle publisher (configure), destroyed by the base class after ``cleanup()``."""
        pub = self.create_lifecycle_publisher(msg_type, topic, qos)
        self._owned_publishers.append(pub)
        return pub

    def active_timer(self, period_s: float, callback, clock=None):
        """A timer (activate), destroyed by the base class after ``deactivate()``. A tick the executor had
        already queued when the timer was destroyed is dropped: rclpy's EventsExecutor delivered one after a
        shutdown transition (test_launch_sim's lifecycle cycle: the ephemeris node's tick with no time mapping)."""
        holder: list = []

        @functools.wraps(callback)
        def while_owned(*args, **kwargs):
            if holder and any(e is holder[0] for e in self._owned_active):
                return callback(*args, **kwargs)
            return None

        timer = self.create_timer(period_s, self.speaking(while_owned), clock=clock)
        holder.append(timer)
        self._owned_active.append(timer)
        return timer

    def active_clock_timer(self, period_s: float, callback):
        """A timer on the node's (ROS) clock (activate), destroyed after ``deactivate()``. With a simulated
        clock ``callback`` also runs after every step of the clock (a clock jump callback): rclpy's
        EventsExecutor can miss a ROS-time timer when the clock jumps (seen in gnss-sim run: a trajectory
        tick missed, so its epoch waited for TF until tf_timeout_s). ``callback`` must act on what the clock
        has reached (both of them may run for one step)."""
        timer = self.active_timer(period_s, callback)
        if self.has_parameter("use_sim_time") and self.get_parameter("use_sim_time").value:
            from rclpy.clock import JumpThreshold
            from rclpy.duration import Duration

            def after_step(_jump):
                try:
                    self.speaking(callback)()
                except Exception as exc:  # noqa: BLE001 - raised into rcl it would be lost
                    self.get_logger().error(f"{type(exc).__name__}: {exc}")

            handle = self.get_clock().create_jump_callback(
                JumpThreshold(min_forward=Duration(nanoseconds=1), min_backward=None, on_clock_change=False),
                post_callback=after_step)
            self._jump_handles.append(handle)
        return timer

    def active_subscription(self, msg_type, topic: str, callback, qos, raw: bool = False):
        """A subscription (activate), destroyed by the base class after ``deactivate()``; ``raw``: the
        callback takes the serialised bytes (gnss_sim_ros2/messages/cdr.py reads them)."""
        sub = self.create_subscription(msg_type, topic, self.speaking(callback), qos, raw=raw)
        self._owned_active.append(sub)
        return sub

    def drop_active(self, entity):
        """Destroy one subscription or timer of ``active_subscription`` / ``active_timer`` before deactivate (a
        topic taken in-process instead: nodes/in_process.py)."""
        if any(e is entity for e in self._owned_active):
            self._owned_active = [e for e in self._owned_active if e is not entity]
            if hasattr(entity, "timer_period_ns"):
                self.destroy_timer(entity)
            else:
                self.destroy_subscription(entity)

    def _release_active(self):
        for handle in self._jump_handles:
            handle.unregister()
        self._jump_handles = []
        for entity in self._owned_active:
            if hasattr(entity, "timer_period_ns"):
                self.destroy_timer(entity)
            else:
                self.destroy_subscription(entity)
        self._owned_active = []

    def _release_publishers(self):
        for pub in self._owned_publishers:
            self.destroy_publisher(pub)
        self._owned_publishers = []

    # ----------------------------------------------------------- parameters
    def read_parameters(self) -> dict:
        """Current values, validated by the table; ValueError names the node and parameter."""
        if self.last_error:
            raise ValueError(self.last_error)
        out = {}
        where = f"node {self.get_name()}"
        for p in params_of(self.PARAMS_KEY):
            param = self.get_parameter_or(p.name, None)
            try:
                value = param.value if param is not None else None
            except Exception:
                value = None
            if value is None:
                value = list(p.default) if isinstance(p.default, list) else p.default
            if isinstance(value, tuple) or type(value).__name__ == "array":
                value = list(value)
            out[p.name] = value
        return validate_node(self.PARAMS_KEY, out, where)

    # ----------------------------------------------------------- lifecycle
    def on_configure(self, state) -> TransitionCallbackReturn:
        try:
            self.params = self.read_parameters()
            self.speaking(self.configure)(self.params)
        except (ValueError, OSError) as exc:
            self.last_error = str(exc)
            self.get_logger().error(f"configure failed: {exc}")
            try:
                self.release()
            except Exception:  # noqa: BLE001 - best effort after a failed configure
                pass
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info("configured")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        ret = super().on_activate(state)  # lifecycle publishers first: activate() may publish
        try:
            self.speaking(self.activate)()
        except Exception as exc:  # noqa: BLE001 - report any failure as the transition's error
            self.last_error = f"activate: {type(exc).__name__}: {exc}"
            self.get_logger().error(self.last_error)
            return TransitionCallbackReturn.FAILURE
        # what configure loaded (scene, ephemeris, modules) out of the garbage collector's sight: a full
        # collection then walks the objects of the run only (one over the loaded process took 150 ms: an
        # epoch that late); the process's few start-up cycles are kept rather than collected
        gc.freeze()
        return ret

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self.deactivate()
        self._release_active()
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        self.release()
        self.params = {}
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        self.release()
        return TransitionCallbackReturn.SUCCESS

    def release(self):
        """Everything the node holds, whatever its state (idempotent): files closed, entities destroyed."""
        self.deactivate()
        self._release_active()
        self.cleanup()
        self._release_publishers()

    # subclasses: make resources in configure/activate, free the rest (files, scenes) in cleanup
    def configure(self, params: dict):
        pass

    def activate(self):
        pass

    def deactivate(self):
        pass

    def cleanup(self):
        pass


def run_origin_ns(node) -> int:
    """ROS time [ns] at which a run's time 0 lies: 0 on a simulated clock (Gazebo, gnss-sim run
    start their /clock at 0), the time of the node's first call on a wall clock (the run starts
    then). A lifecycle cycle (deactivate, cleanup, configure, activate) continues that timeline:
    starting it again would repeat GNSS epochs and the RINEX file names of the first activation."""
    use_sim = node.get_parameter("use_sim_time").value if node.has_parameter("use_sim_time") else False
    if use_sim:
        return 0
    origin = getattr(node, "_run_origin_ns", None)
    if origin is None:
        origin = node._run_origin_ns = node.get_clock().now().nanoseconds
    return origin


class TimeMapping:
    """ROS time <-> GNSS time of a run (parameters start_time and time_mapping).

    ``offset``: GNSS time = start_time + (ROS time - origin), origin from :func:`run_origin_ns`;
    ``utc``: ROS stamps are UNIX time in UTC (a robot on the wall clock of today).
    """

    def __init__(self, start_time_iso: str, mode: str = "offset", origin_ns: int = 0):
        self.start = GnssTime.from_iso(start_time_iso)
        self.mode = mode
        self.origin_ns = int(origin_ns)

    def to_gnss(self, stamp) -> GnssTime:
        if self.mode == "offset":
            ns = stamp.sec * 1_000_000_000 + stamp.nanosec - self.origin_ns
            return ros_time_to_gnss(ns // 1_000_000_000, ns % 1_000_000_000, offset=self.start)
        return ros_time_to_gnss(stamp.sec, stamp.nanosec)

    def to_ros(self, t: GnssTime):
        from builtin_interfaces.msg import Time

        sec, ns = gnss_to_ros_time(t, offset=self.start if self.mode == "offset" else None)
        total = sec * 1_000_000_000 + ns + (self.origin_ns if self.mode == "offset" else 0)
        return Time(sec=total // 1_000_000_000, nanosec=total % 1_000_000_000)


class StopSignals:
    """SIGINT and SIGTERM as a flag that a spin loop polls.

    rclpy's own handlers shut the context down at once, wherever the executor
    is (the container then failed in ``wait set`` with exit 1, a node inside
    ``take_message``); here the loop ends, the nodes free their resources on a
    valid context (RINEX and bag files closed) and the process exits 0.  ros2
    launch sends SIGINT, then SIGTERM after its timeout: both are handled.
    Use with ``rclpy.init(..., signal_handler_options=SignalHandlerOptions.NO)``.
    """

    def __init__(self):
        import signal

        self.signum = None
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, self._on_signal)

    def _on_signal(self, signum, _frame):
        if self.signum is None:
            # a process that has not ended STOP_WATCHDOG_S after the first signal hangs (ros2 launch would SIGKILL
            # it at 5 + 10 s, silently): every thread's stack to stderr, then exit 1, so the log says where
            import faulthandler

            faulthandler.dump_traceback_later(STOP_WATCHDOG_S, exit=True)
        self.signum = signum

    @property
    def stopped(self) -> bool:
        return self.signum is not None


#: seconds from the first SIGINT / SIGTERM to the stack dump and exit of a process that has not ended (StopSignals):
#: under ros2 launch's SIGKILL, 10 s after its SIGINT (sigterm_timeout 5 s, then sigkill_timeout 5 s; a launch
#: test's log: SIGINT, SIGTERM 5 s later, SIGKILL 5 s after that), so the stack reaches the log
STOP_WATCHDOG_S = 9.0


def init_ros(args=None) -> StopSignals:
    """``rclpy.init`` without rclpy's signal handlers, ours installed first."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop = StopSignals()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    return stop


def spin_until_stopped(executor, stop: StopSignals, poll_s: float = 0.1):
    """Spin until a signal (or the context is shut down); the poll bounds the reaction time."""
    while not stop.stopped and executor.context.ok():
        executor.spin_once(timeout_sec=poll_s)


def close_ros(executor, *nodes):
    """After the spin loop: the nodes out of the executor and destroyed, then rclpy shut down."""
    import rclpy

    for node in nodes:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    rclpy.try_shutdown()


def run_node(cls, args=None) -> int:
    """``main`` of a node executable: spin until Ctrl-C / SIGTERM / shutdown, then free the node's
    resources (files closed: a RINEX file stays valid up to its last epoch) and exit 0."""
    stop = init_ros(args)
    node = cls()
    executor = make_executor()
    executor.add_node(node)
    try:
        spin_until_stopped(executor, stop)
    finally:
        node.release()
        close_ros(executor, node)
    return 0


#: environment variable choosing the executor of gnss_sim's processes: "events" (rclpy's EventsExecutor, the
#: default where rclpy has it) or "single" (rclpy's SingleThreadedExecutor)
EXECUTOR_ENV = "GNSS_SIM_EXECUTOR"


def make_executor(context=None):
    """The executor every gnss_sim process spins: rclpy.experimental.EventsExecutor (callbacks dispatched
    from C++: about 10x less executor CPU per callback than the SingleThreadedExecutor, which rebuilds its
    wait set in Python at every spin_once), or the SingleThreadedExecutor where rclpy has no EventsExecutor
    or ``GNSS_SIM_EXECUTOR=single``. Both run every callback in the calling thread, one at a time."""
    import os

    from rclpy.executors import SingleThreadedExecutor

    choice = os.environ.get(EXECUTOR_ENV, "events")
    if choice not in ("events", "single"):
        raise ValueError(f"environment variable {EXECUTOR_ENV} is {choice!r}: one of events, single")
    if choice == "events":
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:          # rclpy before Jazzy
            pass
        else:
            return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def executor_name(executor) -> str:
    return "EventsExecutor" if "EventsExecutor" in type(executor).__name__ else type(executor).__name__
