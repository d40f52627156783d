"""usable_cores (task/cores.py): a cgroup CPU quota caps the affinity mask. The quota
files' formats by hand: cgroup v2's cpu.max, v1's cfs quota and period."""
import os

from lhd_loading_ros.task.cores import cgroup_dirs, quota_cores, usable_cores


def test_quota_files_by_hand():
    assert quota_cores(cpu_max="max 100000\n") is None                 # unlimited
    assert quota_cores(cpu_max="200000 100000\n") == 2                  # 2 CPUs
    assert quota_cores(cpu_max="150000 100000") == 1                    # 1.5 CPUs: one busy thread's worth
    assert quota_cores(cpu_max="350000 100000") == 3                    # 3.5: not 4
    assert quota_cores(cpu_max="50000 100000") == 1                     # half a CPU: at least 1
    assert quota_cores(cfs_quota_us="-1\n", cfs_period_us="100000\n") is None
    assert quota_cores(cfs_quota_us="400000\n", cfs_period_us="100000\n") == 4
    assert quota_cores(cpu_max="garbage") is None and quota_cores() is None


def test_usable_cores_never_exceeds_the_affinity():
    n = usable_cores()
    assert 1 <= n <= len(os.sched_getaffinity(0))
    q = quota_cores(cpu_max=open("/sys/fs/cgroup/cpu.max").read()) if os.path.exists("/sys/fs/cgroup/cpu.max") else None
    if q is not None:
        assert n <= q


def test_the_cgroup_path_and_its_parents(tmp_path):
    """A quota on a parent (a systemd slice) applies: every directory from the process's cgroup up."""
    v2 = cgroup_dirs("0::/system.slice/lhd.service\n", tmp_path)
    assert v2 == [tmp_path / "system.slice" / "lhd.service", tmp_path / "system.slice", tmp_path]
    (tmp_path / "cpu").mkdir()
    v1 = cgroup_dirs("4:memory:/x\n2:cpu,cpuacct:/docker/abc\n1:name=systemd:/\n", tmp_path)
    assert v1 == [tmp_path / "cpu" / "docker" / "abc", tmp_path / "cpu" / "docker", tmp_path / "cpu"]
    assert cgroup_dirs("garbage", tmp_path) == []
