# shellcheck shell=bash
# The project's environment. Source it, do not run it:
#
#     source scripts/env.sh
#
# After it: `python` is .venv's interpreter, rclpy and the messages import, the workspace
# overlay install/ is active (when built), and ament_index finds the installed packages.
#
#   * system mode (/opt/ros/jazzy, recorded by scripts/setup.sh): sources
#     $ACTUATOR_ROS_PREFIX/setup.bash, then the venv (made with --system-site-packages).
#   * wheels mode: the venv is itself the ROS prefix (include/, lib/, share/); sets
#     CMAKE_PREFIX_PATH, AMENT_PREFIX_PATH and LD_LIBRARY_PATH for it.
#
# Safe to source from scripts running under `set -euo pipefail` and an ERR trap: the ROS
# setup scripts are not nounset/errexit-safe, so they are sourced with those options and
# the ERR trap suspended, and the caller's options are restored afterwards.
#
# Knobs: ACTUATOR_ENV_NO_WORKSPACE=1 skips install/setup.bash (used while building).
# Defaults it sets only when unset: RMW_IMPLEMENTATION=rmw_fastrtps_cpp and
# ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (export SUBNET before sourcing to reach other hosts).

_actuator_source_unsafe() {
    # Source a script that may use unset variables or fail internally. The caller's
    # errexit/nounset/pipefail/errtrace and ERR trap are saved and restored (read from $-
    # and `[[ -o ]]`, not from $(set +o): a command substitution does not inherit errexit).
    local _had=() _opt _err_trap _rc=0
    for _opt in errexit nounset pipefail errtrace; do
        if [[ -o $_opt ]]; then _had+=("$_opt"); fi
    done
    _err_trap="$(trap -p ERR)"
    trap - ERR
    set +o errexit +o nounset +o pipefail +o errtrace
    # shellcheck disable=SC1090
    source "$1" || _rc=$?
    for _opt in "${_had[@]}"; do
        set -o "$_opt"
    done
    if [[ -n $_err_trap ]]; then eval "$_err_trap"; fi
    return "$_rc"
}

_actuator_prepend() {
    # _actuator_prepend VAR DIR: put DIR first in the colon list VAR, once.
    local _var=$1 _dir=$2 _cur
    _cur="${!_var-}"
    case ":$_cur:" in
        *":$_dir:"*) ;;
        *) if [[ -n $_cur ]]; then export "$_var=$_dir:$_cur"; else export "$_var=$_dir"; fi ;;
    esac
}

_actuator_env() {
    local _root _venv _site _d
    _root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    _venv="$_root/.venv"
    if [[ ! -x $_venv/bin/python || ! -f $_venv/actuator-env ]]; then
        echo "scripts/env.sh: no set-up found in $_venv: run 'make setup' (scripts/setup.sh) first" >&2
        return 1
    fi
    export ACTUATOR_WS="$_root"
    ACTUATOR_ROS_MODE="$(sed -n 's/^ACTUATOR_ROS_MODE=//p' "$_venv/actuator-env")"
    ACTUATOR_ROS_PREFIX="$(sed -n 's/^ACTUATOR_ROS_PREFIX=//p' "$_venv/actuator-env")"
    export ACTUATOR_ROS_MODE ACTUATOR_ROS_PREFIX

    if [[ $ACTUATOR_ROS_MODE == system ]]; then
        if [[ ! -f $ACTUATOR_ROS_PREFIX/setup.bash ]]; then
            echo "scripts/env.sh: .venv was set up for $ACTUATOR_ROS_PREFIX, which is gone: run 'make setup'" >&2
            return 1
        fi
        _actuator_source_unsafe "$ACTUATOR_ROS_PREFIX/setup.bash" || {
            echo "scripts/env.sh: sourcing $ACTUATOR_ROS_PREFIX/setup.bash failed" >&2
            return 1
        }
    fi

    # Activate the venv (what bin/activate does, without its prompt handling).
    unset PYTHONHOME
    export VIRTUAL_ENV="$_venv"
    _actuator_prepend PATH "$_venv/bin"

    if [[ $ACTUATOR_ROS_MODE == wheels ]]; then
        # The wheels install a ROS prefix into the venv itself.
        _actuator_prepend CMAKE_PREFIX_PATH "$_venv"
        _actuator_prepend AMENT_PREFIX_PATH "$_venv"
        # ros-wheels-bootstrapper would re-exec every Python process once to add these
        # library folders; setting them here (and its guard) saves that and also serves
        # non-Python children.
        _site="$(echo "$_venv"/lib/python3.*/site-packages)"
        for _d in "$_site"/ros_*.libs; do
            if [[ -d $_d ]]; then _actuator_prepend LD_LIBRARY_PATH "$_d"; fi
        done
        _actuator_prepend LD_LIBRARY_PATH "$_venv/lib"
        export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
        # What a Jazzy install's setup.bash sets for the tools (ros2 doctor, launch, rosdep).
        export ROS_DISTRO=jazzy ROS_VERSION=2 ROS_PYTHON_VERSION=3
    fi

    if [[ -z ${ACTUATOR_ENV_NO_WORKSPACE:-} && -f $_root/install/setup.bash ]]; then
        _actuator_source_unsafe "$_root/install/setup.bash" || {
            echo "scripts/env.sh: sourcing $_root/install/setup.bash failed: run 'make build'" >&2
            return 1
        }
    fi

    export ACTUATOR_PYTHON="$_venv/bin/python"
    export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
    export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
    return 0
}

_actuator_env
