"""The lifecycle of a device component, after ros2_control's hardware components.

::

    UNCONFIGURED --configure--> INACTIVE --activate--> ACTIVE
         ^                        |  ^                   |
         |                        |  +---deactivate------+
         +-------- FINALIZED <--cleanup (from INACTIVE, ACTIVE or ERROR)
    any failed transition or failed recovery --> ERROR

The run loop configures and activates every device before the loop and deactivates and
cleans it up afterwards, also after an error.
"""

from __future__ import annotations

from collections.abc import Iterator
from enum import Enum

from hapticframe.devices._health import DeviceHealth

__all__ = ["DeviceError", "DeviceLifecycle", "LifecycleState"]


class DeviceError(RuntimeError):
    """A device cannot go on (a transition failed, or bounded recovery gave up).

    The run loop ends the run with exit 1 after stopping every actuator. The message names
    the device and what failed.

    Parameters
    ----------
    message : str
        What failed, for a person.
    device_id : str or None, optional
        The device's component id (the message should name it too).
    """

    def __init__(self, message: str, *, device_id: str | None = None) -> None:
        super().__init__(message)
        self.device_id = device_id


class LifecycleState(Enum):
    """Where a device is in its lifecycle."""

    UNCONFIGURED = "unconfigured"
    INACTIVE = "inactive"
    ACTIVE = "active"
    FINALIZED = "finalized"
    ERROR = "error"


class DeviceLifecycle:
    """Mixin for device components: checked transitions, health, bounded recovery.

    Subclasses override the hooks; the public methods check the state, call the hook and
    move. A hook that raises during ``configure``/``activate`` puts the device in ERROR and
    surfaces as :class:`DeviceError`.

    - ``on_configure``: open the transport and identify the device (as ros2_control's
      ``on_configure`` sets up communication); nothing moves or streams yet.
    - ``on_activate``: start the data flow (streaming, the operating mode, a tare).
    - ``on_deactivate``: stop the data flow. Must tolerate a link that is already gone;
      :class:`OSError` from it is swallowed.
    - ``on_cleanup``: close the transport and release what ``on_configure`` took.
    - ``on_recover(error)``: bring the device back after ``error`` (close, wait a backoff
      delay on the device's clock, reopen, handshake); raise to fail.

    Attributes
    ----------
    max_recoveries : int
        Consecutive failed recovery attempts after which :meth:`recover` gives up.
    live : bool
        True when the device is real hardware (paced by the wall clock), False when it is
        emulated and paced by the simulation.
    """

    max_recoveries: int = 3
    live: bool = False

    # --- state -------------------------------------------------------------------------
    @property
    def lifecycle_state(self) -> LifecycleState:
        """The current state."""
        state: LifecycleState = self.__dict__.get("_lifecycle_state", LifecycleState.UNCONFIGURED)
        return state

    def _set_state(self, state: LifecycleState) -> None:
        self.__dict__["_lifecycle_state"] = state

    @property
    def health(self) -> DeviceHealth:
        """This device's counters (created on first use)."""
        health = self.__dict__.get("_device_health")
        if health is None:
            health = self.__dict__["_device_health"] = DeviceHealth()
        assert isinstance(health, DeviceHealth)
        return health

    @property
    def device_id(self) -> str:
        """The component id (``self.id``), else the class name: for messages."""
        name = getattr(self, "id", None)
        return name if isinstance(name, str) else type(self).__name__

    @property
    def recovery_streak(self) -> int:
        """Failed recovery attempts in a row so far (0 after a success)."""
        streak: int = self.__dict__.get("_recovery_streak", 0)
        return streak

    # --- hooks -------------------------------------------------------------------------
    def on_configure(self) -> None:
        """Open the link and identify the device (nothing moves or streams yet)."""

    def on_activate(self) -> None:
        """Start the data flow (streaming, an operating mode, a tare)."""

    def on_deactivate(self) -> None:
        """Stop the data flow (tolerate a link that is already gone)."""

    def on_cleanup(self) -> None:
        """Close the link and release what :meth:`on_configure` took."""

    def on_recover(self, error: Exception) -> None:
        """Bring the device back after ``error``; raise when it cannot be (default: cannot)."""
        raise error

    def recovery_steps(self, error: Exception) -> Iterator[None]:
        """One recovery attempt in steps that never wait: yield where the attempt waits for
        the device or for time to pass (the next :meth:`continue_recovery` goes on from
        there), return when the device is back, raise when it is not. Default: the whole
        of :meth:`on_recover` in one step."""
        self.on_recover(error)
        yield from ()

    # --- transitions -------------------------------------------------------------------
    def _fail(self, what: str, exc: BaseException) -> DeviceError:
        self._set_state(LifecycleState.ERROR)
        if isinstance(exc, DeviceError):
            return exc
        return DeviceError(f"device {self.device_id!r}: {what} failed: {exc}",
                           device_id=self.device_id)

    def configure(self) -> None:
        """UNCONFIGURED (or FINALIZED) → INACTIVE; a no-op when already configured."""
        state = self.lifecycle_state
        if state in (LifecycleState.INACTIVE, LifecycleState.ACTIVE):
            return
        if state is LifecycleState.ERROR:
            raise DeviceError(
                f"device {self.device_id!r} is in ERROR: clean it up before configuring again",
                device_id=self.device_id,
            )
        try:
            self.on_configure()
        except Exception as exc:
            raise self._fail("configure", exc) from exc
        self._set_state(LifecycleState.INACTIVE)

    def activate(self) -> None:
        """INACTIVE → ACTIVE; a no-op when active; DeviceError from any other state."""
        state = self.lifecycle_state
        if state is LifecycleState.ACTIVE:
            return
        if state is not LifecycleState.INACTIVE:
            raise DeviceError(
                f"device {self.device_id!r} cannot activate from {state.value}: "
                "configure it first",
                device_id=self.device_id,
            )
        try:
            self.on_activate()
        except Exception as exc:
            self._deactivate_quietly()
            raise self._fail("activate", exc) from exc
        self.__dict__["_recovery_streak"] = 0
        self._set_state(LifecycleState.ACTIVE)

    def deactivate(self) -> None:
        """ACTIVE → INACTIVE; a no-op in any other state. Never raises for a link that is gone."""
        if self.lifecycle_state is not LifecycleState.ACTIVE:
            return
        self._set_state(LifecycleState.INACTIVE)
        try:
            self.on_deactivate()
        except OSError:
            pass  # the device is gone or unplugged: there is nothing left to stop

    def cleanup(self) -> None:
        """Release everything and enter FINALIZED; a no-op when there is nothing to clean."""
        state = self.lifecycle_state
        if state in (LifecycleState.UNCONFIGURED, LifecycleState.FINALIZED):
            return
        if state is LifecycleState.ACTIVE:
            self.deactivate()
        self.__dict__["_recovery"] = None  # a recovery under way ends with the link
        self._set_state(LifecycleState.FINALIZED)
        try:
            self.on_cleanup()
        except OSError:  # closing a link whose device is gone: nothing left to release
            pass

    def recover(self, error: Exception) -> None:
        """Try to bring the device back after ``error``, a bounded number of times.

        Each attempt counts ``health.recoveries`` and calls :meth:`on_recover`. A success
        returns (and resets the streak); after ``max_recoveries`` failures in a row the device
        enters ERROR, is deactivated best-effort, and :class:`DeviceError` is raised.

        Raises
        ------
        DeviceError
            When recovery failed, or the device is not configured.
        """
        state = self.lifecycle_state
        if state not in (LifecycleState.INACTIVE, LifecycleState.ACTIVE):
            raise DeviceError(
                f"device {self.device_id!r} cannot recover from {state.value} "
                f"(after: {error})",
                device_id=self.device_id,
            )
        last: Exception = error
        while self.recovery_streak < self.max_recoveries:
            self.health.recoveries += 1
            try:
                self.on_recover(last)
            except Exception as exc:
                self.__dict__["_recovery_streak"] = self.recovery_streak + 1
                last = exc
                continue
            self.__dict__["_recovery_streak"] = 0
            return
        self.__dict__["_recovery_streak"] = 0
        self._set_state(LifecycleState.ERROR)
        self._deactivate_quietly()
        raise DeviceError(
            f"device {self.device_id!r} did not recover after {self.max_recoveries} attempts "
            f"(first error: {error}; last: {last})",
            device_id=self.device_id,
        ) from last

    # --- recovery that never blocks the loop ---------------------------------------------
    @property
    def recovering(self) -> bool:
        """Whether a recovery started by :meth:`begin_recovery` is under way."""
        return self.__dict__.get("_recovery") is not None

    def begin_recovery(self, error: Exception) -> None:
        """Start recovering after ``error`` without waiting: each later
        :meth:`continue_recovery` runs one step of :meth:`recovery_steps` (a read of a
        recovering device delivers nothing and returns at once). A no-op while recovering.

        Raises
        ------
        DeviceError
            When the device is not configured.
        """
        if self.recovering:
            return
        state = self.lifecycle_state
        if state not in (LifecycleState.INACTIVE, LifecycleState.ACTIVE):
            raise DeviceError(
                f"device {self.device_id!r} cannot recover from {state.value} "
                f"(after: {error})",
                device_id=self.device_id,
            )
        self.health.recoveries += 1
        self.__dict__["_recovery"] = (self.recovery_steps(error), error)

    def continue_recovery(self) -> bool:
        """One step of the recovery under way; True once the device is back (or when none
        is under way). A failed attempt starts the next; after ``max_recoveries`` failed
        attempts in a row the device enters ERROR, is deactivated and
        :class:`DeviceError` is raised, as from :meth:`recover`."""
        under_way = self.__dict__.get("_recovery")
        if under_way is None:
            return True
        steps, first = under_way
        try:
            next(steps)
        except StopIteration:
            self.__dict__["_recovery"] = None
            self.__dict__["_recovery_streak"] = 0
            return True
        except Exception as exc:
            streak = self.recovery_streak + 1
            if streak >= self.max_recoveries:
                self.__dict__["_recovery"] = None
                self.__dict__["_recovery_streak"] = 0
                self._set_state(LifecycleState.ERROR)
                self._deactivate_quietly()
                raise DeviceError(
                    f"device {self.device_id!r} did not recover after {self.max_recoveries} "
                    f"attempts (first error: {first}; last: {exc})",
                    device_id=self.device_id,
                ) from exc
            self.__dict__["_recovery_streak"] = streak
            self.health.recoveries += 1
            self.__dict__["_recovery"] = (self.recovery_steps(exc), first)
        return False

    def _deactivate_quietly(self) -> None:
        try:
            self.on_deactivate()
        except Exception:  # best effort: the device has already failed
            pass
