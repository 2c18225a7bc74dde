import pytest
import torch


@pytest.fixture(autouse=True)
def one_torch_thread():
    # The test machine is shared: with several processes on 2 cores, OpenMP threads that spin-wait for
    # each other make tiny convolutions ~10x slower than one thread does. Restored after each test.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
