"""Many cases of one model: the scan and its file (`scan`), the journal of finished cases and the
atomic gather (`store`), the fork server started at the command's first line (`server`) and the
worker process's set-up (`worker`)."""
