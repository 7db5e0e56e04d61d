#!/usr/bin/env bash
# Installs evarnode as the hardened bedside service (docs/SECURITY.md): the binary, a
# dedicated system user, the systemd unit, the udev rule for the C-arm adapter, the GigE
# receive-buffer cap (sysctl) and a starting /etc/evarnode/node.json (kept if present).
# Idempotent; needs root. The device choices are kept in /etc/evarnode/bedside.conf, so
# a re-install (an update) without flags keeps them; --no-... drops one.
#
#   sudo scripts/install-bedside.sh [--carm-usb VID:PID] [--grabber-usb VID:PID] [--packet-socket]
#   scripts/install-bedside.sh --render DIR [--bin PATH] [...]   (writes the files into DIR only)
#
# --carm-usb      the C-arm adapter (a libusb device for "carm": "usb:VID:PID", or the
#                 USB-serial converter behind "serial:/dev/evarnode-carm"); lsusb shows it
# --grabber-usb   a USB frame grabber, to be named /dev/evarnode-grabber
# --packet-socket grant CAP_NET_RAW for Aravis's packet socket (GigE at high rates)
# --no-carm-usb, --no-grabber-usb, --no-packet-socket   drop a choice kept from before
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
render="" bin=/usr/local/bin/evarnode carm="" grabber="" packet_socket=""
usage() { sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit "${1:-0}"; }
unset_carm=0 unset_grabber=0
while [ $# -gt 0 ]; do
  case "$1" in
    --render) render=${2:?--render needs a directory}; shift 2 ;;
    --bin) bin=${2:?--bin needs a path}; shift 2 ;;
    --carm-usb) carm=${2:?--carm-usb needs VID:PID}; shift 2 ;;
    --grabber-usb) grabber=${2:?--grabber-usb needs VID:PID}; shift 2 ;;
    --packet-socket) packet_socket=1; shift ;;
    --no-carm-usb) unset_carm=1; shift ;;
    --no-grabber-usb) unset_grabber=1; shift ;;
    --no-packet-socket) packet_socket=0; shift ;;
    -h|--help) usage 0 ;;
    *) echo "install-bedside.sh: unknown argument '$1'" >&2; usage 2 >&2 ;;
  esac
done
if [ -n "$carm" ] && [ "$unset_carm" = 1 ]; then
  echo "install-bedside.sh: --carm-usb and --no-carm-usb contradict each other" >&2; exit 2
fi
if [ -n "$grabber" ] && [ "$unset_grabber" = 1 ]; then
  echo "install-bedside.sh: --grabber-usb and --no-grabber-usb contradict each other" >&2; exit 2
fi
if [ -z "$render" ] && [ "$(id -u)" -ne 0 ]; then
  echo "install-bedside.sh: run as root (sudo), or use --render DIR" >&2; exit 1
fi
vid_pid='^[0-9a-fA-F]{4}:[0-9a-fA-F]{4}$'
for id in "$carm" "$grabber"; do
  if [ -n "$id" ] && ! [[ "$id" =~ $vid_pid ]]; then
    echo "install-bedside.sh: '$id' is not VID:PID (four hexadecimal digits each, as lsusb prints)" >&2
    exit 2
  fi
done

# The choices of the last install: read as data (never sourced), each line checked.
conf=${render:+$render/bedside.conf}
conf=${conf:-/etc/evarnode/bedside.conf}
if [ -f "$conf" ]; then
  line_no=0 seen=" "
  while IFS= read -r line || [ -n "$line" ]; do
    line_no=$((line_no + 1))
    if [[ "$line" == *$'\r' ]]; then
      echo "install-bedside.sh: $conf line $line_no: a CRLF line ending (Windows); save it with Unix line endings" >&2
      exit 2
    fi
    case "$line" in
      ''|'#'*) continue ;;
    esac
    key=${line%%=*} value=${line#*=}
    if [[ "$seen" == *" $key "* ]]; then
      echo "install-bedside.sh: $conf line $line_no: $key is given twice; keep one" >&2
      exit 2
    fi
    seen+="$key "
    ok=0
    case "$key" in
      carm_usb|grabber_usb) [[ -z "$value" || "$value" =~ $vid_pid ]] && ok=1 ;;
      packet_socket) [[ "$value" =~ ^[01]$ ]] && ok=1 ;;
    esac
    if [ "$ok" = 0 ] || [ "$key" = "$line" ]; then
      echo "install-bedside.sh: $conf line $line_no: '$line' is not carm_usb=VID:PID, grabber_usb=VID:PID or packet_socket=0|1; fix or delete the file" >&2
      exit 2
    fi
    case "$key" in
      carm_usb) [ -n "$carm" ] || [ "$unset_carm" = 1 ] || { carm=$value; [ -z "$value" ] || echo "evarnode: C-arm adapter $value, kept from $conf"; } ;;
      grabber_usb) [ -n "$grabber" ] || [ "$unset_grabber" = 1 ] || { grabber=$value; [ -z "$value" ] || echo "evarnode: USB grabber $value, kept from $conf"; } ;;
      packet_socket) [ -n "$packet_socket" ] || { packet_socket=$value; [ "$value" = 0 ] || echo "evarnode: packet socket, kept from $conf"; } ;;
    esac
  done < "$conf"
fi
packet_socket=${packet_socket:-0}

# The files, into a staging directory.
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
escaped_bin=$(printf '%s' "$bin" | sed 's/[&|\\]/\\&/g')
sed "s|/usr/local/bin/evarnode|$escaped_bin|" "$root/scripts/bedside/evarnode.service" > "$stage/evarnode.service"
cp "$root/scripts/bedside/evarnode-packet-socket.conf" "$stage/packet-socket.conf"
{
  echo "# evarnode bedside devices (written by scripts/install-bedside.sh; docs/SECURITY.md)."
  echo "# V4L2 grabbers are group \"video\" and serial ports group \"dialout\" on Debian already;"
  echo "# the service user is in both. This file adds the C-arm adapter and stable names."
  if [ -n "$carm" ]; then
    v=${carm%%:*} p=${carm##*:}
    v=${v,,} p=${p,,}
    echo "SUBSYSTEM==\"usb\", ENV{DEVTYPE}==\"usb_device\", ATTR{idVendor}==\"$v\", ATTR{idProduct}==\"$p\", GROUP=\"evarnode\", MODE=\"0660\""
    echo "SUBSYSTEM==\"tty\", ATTRS{idVendor}==\"$v\", ATTRS{idProduct}==\"$p\", GROUP=\"dialout\", MODE=\"0660\", SYMLINK+=\"evarnode-carm\""
  fi
  if [ -n "$grabber" ]; then
    v=${grabber%%:*} p=${grabber##*:}
    v=${v,,} p=${p,,}
    echo "SUBSYSTEM==\"video4linux\", ATTRS{idVendor}==\"$v\", ATTRS{idProduct}==\"$p\", ATTR{index}==\"0\", GROUP=\"video\", MODE=\"0660\", SYMLINK+=\"evarnode-grabber\""
  fi
} > "$stage/70-evarnode.rules"

{
  echo "# The choices of the last scripts/install-bedside.sh; a re-install without flags keeps them."
  echo "carm_usb=$carm"
  echo "grabber_usb=$grabber"
  echo "packet_socket=$packet_socket"
} > "$stage/bedside.conf"

if [ -n "$render" ]; then
  mkdir -p "$render/evarnode.service.d"
  cp "$stage/evarnode.service" "$stage/70-evarnode.rules" "$stage/bedside.conf" "$root/scripts/bedside/60-evarnode-gige.conf" "$render/"
  if [ "$packet_socket" = 1 ]; then
    cp "$stage/packet-socket.conf" "$render/evarnode.service.d/"
  else
    rm -f "$render/evarnode.service.d/packet-socket.conf"
  fi
  echo "evarnode: bedside files written to $render"
  exit 0
fi

EVAR_BUILD_DIR=${EVAR_BUILD_DIR:-$root/build} "$root/scripts/build.sh"
install -D -m 0755 "${EVAR_BUILD_DIR:-$root/build}/app/evarnode" "$bin"
getent group evarnode >/dev/null || addgroup --system evarnode
id evarnode >/dev/null 2>&1 || adduser --system --ingroup evarnode --home /var/lib/evarnode --no-create-home evarnode
install -D -m 0644 "$stage/evarnode.service" /etc/systemd/system/evarnode.service
if [ "$packet_socket" = 1 ]; then
  install -D -m 0644 "$stage/packet-socket.conf" /etc/systemd/system/evarnode.service.d/packet-socket.conf
else
  rm -f /etc/systemd/system/evarnode.service.d/packet-socket.conf
fi
install -D -m 0644 "$stage/70-evarnode.rules" /etc/udev/rules.d/70-evarnode.rules
install -D -m 0644 "$root/scripts/bedside/60-evarnode-gige.conf" /etc/sysctl.d/60-evarnode-gige.conf
sysctl -q -p /etc/sysctl.d/60-evarnode-gige.conf ||
  echo "evarnode: could not raise net.core.rmem_max here (a container?); it applies from the next boot" >&2
install -D -m 0644 "$root/docs/SECURITY.md" /usr/local/share/doc/evarnode/SECURITY.md
install -d -m 0750 -g evarnode /etc/evarnode
install -m 0644 "$stage/bedside.conf" /etc/evarnode/bedside.conf
if [ ! -e /etc/evarnode/node.json ]; then
  install -m 0640 -g evarnode "$root/scripts/bedside/node.json" /etc/evarnode/node.json
  echo "evarnode: edit /etc/evarnode/node.json (scene, registration, detector, grabber, C-arm link)"
fi
if command -v udevadm >/dev/null; then
  udevadm control --reload && udevadm trigger --subsystem-match=usb --subsystem-match=tty --subsystem-match=video4linux ||
    echo "evarnode: udev is not running here; the rule applies from the next boot" >&2
fi
if [ -d /run/systemd/system ]; then
  systemctl daemon-reload
  systemctl enable evarnode.service
  echo "evarnode: installed; start with: systemctl start evarnode   (log: journalctl -u evarnode)"
else
  echo "evarnode: installed; systemd is not running here, so the unit was not enabled"
fi
