"""A pyusb backend (``usb.backend.IBackend``) that plays a DJI USB device from a script of bulk transfers.

Used by the tests and by the virtual drone to deliver telemetry through the real pyusb stack:
``usb.core.find(idVendor=0x2CA3, backend=FakeUsbBackend(...))`` finds a device with a CDC-like interface 0 and
the DUML vendor interface 1 (class 0xFF, subclass 0x43) holding bulk OUT 0x04 and bulk IN 0x85.

The IN endpoint serves the queued items in order: ``bytes`` are returned by bulk reads (split when larger
than the read buffer); an exception instance is raised by the read that reaches it (use
:func:`disconnect_error` for what libusb reports when a cable is pulled); an empty queue times out like a
quiet device (``usb.core.USBTimeoutError``). :meth:`FakeUsbBackend.push` adds items from another thread.
"""

from __future__ import annotations

import array
import collections
import errno
import threading
from types import SimpleNamespace

import usb.backend
import usb.core

from capture.transports import DJI_VENDOR_ID, DUML_INTERFACE_SUBCLASS

BULK_OUT_ENDPOINT = 0x04
BULK_IN_ENDPOINT = 0x85
_BULK = 0x02
_MAX_PACKET_SIZE = 512


def disconnect_error() -> usb.core.USBError:
    """The error pyusb raises when the device is gone (libusb LIBUSB_ERROR_NO_DEVICE / ENODEV)."""
    return usb.core.USBError("No such device (it may have been disconnected)", error_code=-4, errno=errno.ENODEV)


def _endpoint(address: int) -> SimpleNamespace:
    return SimpleNamespace(bLength=7, bDescriptorType=5, bEndpointAddress=address, bmAttributes=_BULK,
                           wMaxPacketSize=_MAX_PACKET_SIZE, bInterval=0, bRefresh=0, bSynchAddress=0,
                           extra_descriptors=[])


def _interface(number: int, cls: int, subclass: int, endpoints: list[int]) -> SimpleNamespace:
    return SimpleNamespace(bLength=9, bDescriptorType=4, bInterfaceNumber=number, bAlternateSetting=0,
                           bNumEndpoints=len(endpoints), bInterfaceClass=cls, bInterfaceSubClass=subclass,
                           bInterfaceProtocol=1, iInterface=0, extra_descriptors=[],
                           endpoints=[_endpoint(a) for a in endpoints])


class FakeUsbBackend(usb.backend.IBackend):
    """One fake DJI device (``vendor_id``/``product_id``) whose bulk IN endpoint serves ``items``."""

    def __init__(self, items=(), vendor_id: int = DJI_VENDOR_ID, product_id: int = 0x001F) -> None:
        super().__init__()
        self.device = SimpleNamespace(
            bLength=18, bDescriptorType=1, bcdUSB=0x0200, bDeviceClass=0xEF, bDeviceSubClass=2, bDeviceProtocol=1,
            bMaxPacketSize0=64, idVendor=vendor_id, idProduct=product_id, bcdDevice=0x0100, iManufacturer=0,
            iProduct=0, iSerialNumber=0, bNumConfigurations=1, address=5, bus=1, port_number=2, port_numbers=(2,),
            speed=3)
        self.interfaces = [_interface(0, 0x02, 0x02, []),
                           _interface(1, 0xFF, DUML_INTERFACE_SUBCLASS, [BULK_OUT_ENDPOINT, BULK_IN_ENDPOINT])]
        self.configuration = SimpleNamespace(bLength=9, bDescriptorType=2, wTotalLength=64,
                                             bNumInterfaces=len(self.interfaces), bConfigurationValue=1,
                                             iConfiguration=0, bmAttributes=0x80, bMaxPower=250, extra_descriptors=[])
        self._queue = collections.deque(items)
        self._ready = threading.Condition()
        self.written = bytearray()  # everything the host sent to the OUT endpoint
        self.opened = 0  # how many times the host opened the device (reconnects + 1)
        self.delivered = bytearray()  # every byte handed to the host so far

    def push(self, item) -> None:
        """Queue ``bytes`` for the IN endpoint, or an exception for the next read to raise."""
        with self._ready:
            self._queue.append(item)
            self._ready.notify_all()

    def enumerate_devices(self):
        yield self.device

    def get_device_descriptor(self, dev):
        return dev

    def get_configuration_descriptor(self, dev, config):
        return self.configuration

    def get_interface_descriptor(self, dev, intf, alt, config):
        if alt != 0:
            raise IndexError(f"interface {intf} has only alternate setting 0")
        return self.interfaces[intf]

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        return self.interfaces[intf].endpoints[ep]

    def open_device(self, dev):
        self.opened += 1
        return SimpleNamespace(device=dev)

    def close_device(self, dev_handle) -> None:
        pass

    def set_configuration(self, dev_handle, config_value) -> None:
        pass

    def get_configuration(self, dev_handle) -> int:
        return self.configuration.bConfigurationValue

    def set_interface_altsetting(self, dev_handle, intf, altsetting) -> None:
        pass

    def claim_interface(self, dev_handle, intf) -> None:
        pass

    def release_interface(self, dev_handle, intf) -> None:
        pass

    def is_kernel_driver_active(self, dev_handle, intf) -> bool:
        return False

    def clear_halt(self, dev_handle, ep) -> None:
        pass

    def ctrl_transfer(self, dev_handle, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        raise usb.core.USBError("control transfers are not scripted", error_code=-12, errno=errno.ENOSYS)

    def bulk_write(self, dev_handle, ep, intf, data, timeout) -> int:
        self.written.extend(bytes(data))
        return len(data)

    def bulk_read(self, dev_handle, ep, intf, buff: array.array, timeout) -> int:
        with self._ready:
            if not self._queue and not self._ready.wait_for(lambda: self._queue, timeout=timeout / 1000):
                raise usb.core.USBTimeoutError("Operation timed out", error_code=-7, errno=errno.ETIMEDOUT)
            item = self._queue.popleft()
            if isinstance(item, BaseException):
                raise item
            size = len(buff) * buff.itemsize
            if len(item) > size:
                self._queue.appendleft(item[size:])
                item = item[:size]
            buff[:len(item)] = array.array("B", item)
            self.delivered.extend(item)
            return len(item)
