# The users' Slurm array-job script, host/cli/slurm/precompute-array.sh
# (test_slurm.sh): hl.slurm.array runs it on a real one-node Slurm started
# on this machine, where four shards and their merge must equal one run
# byte for byte; hl.slurm.requeue has Slurm requeue a shard part-way, which
# must resume and still give the same bytes; hl.slurm.bounces runs the two
# phases of --bounces (direct rows, then the bounces from their merge),
# which must equal one run with --bounces. They skip (77) without root or
# without Debian's slurm-wlm and munge (setup.sh installs them for
# `./setup.sh test`). Each runs its own cluster (daemons, key, config, free
# ports), so they run beside each other and the other tests.
# hl.slurm.usage checks the script's refusals, which need no cluster.
foreach(c array requeue bounces usage)
  add_test(NAME hl.slurm.${c} COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/slurm/test_slurm.sh ${c})
  set_tests_properties(hl.slurm.${c} PROPERTIES
    ENVIRONMENT "HL_BIN=$<TARGET_FILE:haarlight>;HL_REPO_DATA=${CMAKE_SOURCE_DIR}/data;HL_SRC=${CMAKE_SOURCE_DIR}"
    SKIP_RETURN_CODE 77 TIMEOUT 600)
endforeach()
