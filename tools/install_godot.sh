#!/usr/bin/env bash
# Installs Godot >= 4.6 (with Jolt) from Debian's unstable suite into a private folder, without touching
# the system: apt resolves the package closure against an empty private dpkg status, downloads the .debs,
# and dpkg -x unpacks them into one root. tools/godot then starts that Godot through the root's own
# dynamic loader (its glibc is newer than the machine's). Idempotent: a finished install is kept.
#   install_godot.sh CACHE_DIR          Godot
#   install_godot.sh CACHE_DIR render   Godot and Mesa's OpenGL drivers, to render under Xvfb (punch render)
set -euo pipefail

root_dir="${1:?usage: install_godot.sh CACHE_DIR [render]}"
root_dir="$(mkdir -p "$root_dir" && cd "$root_dir" && pwd)"
sysroot="$root_dir/root"
stamp="$root_dir/.installed"
packages=(godot)
if [[ "${2:-}" == "render" ]]; then
    packages+=(libgl1 libglx-mesa0 libegl1 libegl-mesa0 libgl1-mesa-dri)
fi

# The stamp lists what is installed; keep it if it has every package wanted now.
if [[ -f "$stamp" && -x "$sysroot/usr/bin/godot" ]]; then
    read -r -a installed < "$stamp" || true
    [[ ${#installed[@]} -eq 0 ]] && installed=(godot)  # stamps from before the list was written
    missing=0
    for package in "${packages[@]}"; do
        [[ " ${installed[*]} " == *" $package "* ]] || missing=1
    done
    (( missing )) || exit 0
    for package in "${installed[@]}"; do
        [[ " ${packages[*]} " == *" $package "* ]] || packages+=("$package")
    done
fi
if ! command -v apt-get >/dev/null || ! command -v dpkg >/dev/null; then
    echo "error: no Godot >= 4.6 was found and this machine has no apt-get/dpkg to install one." >&2
    echo "       Install Godot 4.6 or newer yourself and run again with GODOT=/path/to/godot." >&2
    exit 3
fi

apt_state="$root_dir/apt"
mkdir -p "$apt_state/lists/partial" "$apt_state/cache/archives/partial" "$apt_state/etc/apt.conf.d" "$apt_state/etc/preferences.d"
: > "$apt_state/status"
echo "deb http://deb.debian.org/debian sid main" > "$apt_state/etc/sources.list"
apt_opts=(
    -o "Dir::State=$apt_state" -o "Dir::State::status=$apt_state/status"
    -o "Dir::State::Lists=$apt_state/lists" -o "Dir::Cache=$apt_state/cache"
    -o "Dir::Etc::SourceList=$apt_state/etc/sources.list" -o "Dir::Etc::SourceParts=/nonexistent"
    -o "Dir::Etc::Parts=$apt_state/etc/apt.conf.d" -o "Dir::Etc::PreferencesParts=$apt_state/etc/preferences.d"
    -o "Dir::Etc::Preferences=/nonexistent"
    -o "APT::Architecture=amd64" -o "APT::Architectures::=amd64" -o "Acquire::Languages=none"
    -o "Debug::NoLocking=1" -o "APT::Install-Recommends=false" -o "APT::Sandbox::User=root"
)

echo "Installing ${packages[*]} from Debian unstable into $root_dir (about 150 MB for Godot, once)..."
apt-get "${apt_opts[@]}" -qq update
apt-get "${apt_opts[@]}" -qq -y --download-only install "${packages[@]}" >/dev/null

rm -rf "$sysroot.partial"
mkdir -p "$sysroot.partial"
for deb in "$apt_state"/cache/archives/*.deb; do
    dpkg -x "$deb" "$sysroot.partial"
done
rm -rf "$sysroot"
mv "$sysroot.partial" "$sysroot"
# The downloaded .debs are not needed once unpacked.
rm -f "$apt_state"/cache/archives/*.deb "$apt_state"/cache/*.bin
echo "${packages[*]}" > "$stamp"
echo "Godot installed: $sysroot/usr/bin/godot"
