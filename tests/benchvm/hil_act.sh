#!/bin/sh
# hil's scripted operator in the bench VM (hil --act "tests/benchvm/hil_act.sh FIFO"): the
# hand of simdrive. hil runs "hil_act.sh FIFO ACTION" with HIL_NODE and HIL_MOVE set; a move by
# hand becomes simdrive's push fault on that node, a release clears it. The FIFO is simdrive's
# stdin (one fault SPEC per line).
fifo=$1 action=$2
case "$action" in
  *.move_positive) echo "push:node=${HIL_NODE:?},move=${HIL_MOVE:?}" > "$fifo" ;;
  *.release) echo "clear:node=${HIL_NODE:?}" > "$fifo" ;;
  *) echo "hil_act.sh: no scripted answer to $action" >&2; exit 1 ;;
esac
