# Sourced by the two-namespace scripts: two network namespaces joined by a veth pair, each
# with only its veth end (10.x.0.1 and 10.x.0.2/24) and loopback, removed on exit.
#   two_namespaces NS_A NS_B VETH_A VETH_B SUBNET   (SUBNET: "10.77.0", ...)
# Needs root and iproute2.
two_namespaces() {
  local a=$1 b=$2 va=$3 vb=$4 net=$5
  TWO_NS=("$a" "$b")
  trap 'for ns in "${TWO_NS[@]}"; do ip netns del "$ns" 2>/dev/null || true; done' EXIT
  for ns in "$a" "$b"; do ip netns del "$ns" 2>/dev/null || true; done
  ip netns add "$a"
  ip netns add "$b"
  ip link add "$va" type veth peer name "$vb"
  ip link set "$va" netns "$a"
  ip link set "$vb" netns "$b"
  ip -n "$a" addr add "$net.1/24" dev "$va"
  ip -n "$b" addr add "$net.2/24" dev "$vb"
  for ns in "$a" "$b"; do ip -n "$ns" link set lo up; done
  ip -n "$a" link set "$va" up
  ip -n "$b" link set "$vb" up
}
