/* Take serialized messages from an rcl subscription in batches, without rclpy's per-message cost.
 *
 * rclpy's Subscription.take_message(raw=True) builds a dict of the message info and a tuple for
 * every message (4.3 us per Imu message here, against 1.8 us in a batch from this module); the
 * recorder's take thread spent most of its time there.
 * This module takes up to a count or byte budget in one call and returns columns: the payloads
 * and three lists of integers, which BagWriter.write_batch takes as they are.
 *
 * librcl is not linked: the caller passes the address of rcl_take_serialized_message (from the
 * librcl that rclpy loaded) and of the rcl_subscription_t (rclpy's handle.pointer). So the module
 * builds with nothing but the Python headers. The structs below mirror the ROS 2 Jazzy headers
 * (rcutils/allocator.h, rcutils/types/uint8_array.h, rmw/types.h); tests compare every column with
 * what rclpy takes from the same publisher.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct
{
  void * (*allocate)(size_t size, void * state);
  void (*deallocate)(void * pointer, void * state);
  void * (*reallocate)(void * pointer, size_t size, void * state);
  void * (*zero_allocate)(size_t count, size_t size, void * state);
  void * state;
} rcutils_allocator_t;

typedef struct
{
  uint8_t * buffer;
  size_t buffer_length;
  size_t buffer_capacity;
  rcutils_allocator_t allocator;
} rcl_serialized_message_t;

#define RMW_GID_STORAGE_SIZE 16u

typedef struct
{
  const char * implementation_identifier;
  uint8_t data[RMW_GID_STORAGE_SIZE];
} rmw_gid_t;

typedef struct
{
  int64_t source_timestamp;
  int64_t received_timestamp;
  uint64_t publication_sequence_number;
  uint64_t reception_sequence_number;
  rmw_gid_t publisher_gid;
  bool from_intra_process;
} rmw_message_info_t;

typedef int32_t (*take_serialized_fn)(
  const void * subscription, rcl_serialized_message_t * message, rmw_message_info_t * info,
  void * allocation);

#define RCL_RET_OK 0
#define RCL_RET_SUBSCRIPTION_TAKE_FAILED 401

static void * allocate(size_t size, void * state)
{
  (void)state;
  return malloc(size);
}

static void deallocate(void * pointer, void * state)
{
  (void)state;
  free(pointer);
}

static void * reallocate(void * pointer, size_t size, void * state)
{
  (void)state;
  return realloc(pointer, size);
}

static void * zero_allocate(size_t count, size_t size, void * state)
{
  (void)state;
  return calloc(count, size);
}

/* Append a new reference to list; steal it (also on failure). */
static int append_new(PyObject * list, PyObject * item)
{
  if (item == NULL) {
    return -1;
  }
  int failed = PyList_Append(list, item);
  Py_DECREF(item);
  return failed;
}

static PyObject * take_serialized(PyObject * self, PyObject * args)
{
  (void)self;
  unsigned long long take_address;
  unsigned long long subscription_address;
  Py_ssize_t max_count;
  Py_ssize_t max_bytes;
  if (!PyArg_ParseTuple(
      args, "KKnn", &take_address, &subscription_address, &max_count, &max_bytes))
  {
    return NULL;
  }
  if (take_address == 0 || subscription_address == 0) {
    PyErr_SetString(PyExc_ValueError, "take_serialized: null function or subscription");
    return NULL;
  }
  take_serialized_fn take = (take_serialized_fn)(uintptr_t)take_address;
  const void * subscription = (const void *)(uintptr_t)subscription_address;

  PyObject * payloads = PyList_New(0);
  PyObject * received = PyList_New(0);
  PyObject * sources = PyList_New(0);
  PyObject * sequences = PyList_New(0);
  if (payloads == NULL || received == NULL || sources == NULL || sequences == NULL) {
    goto fail;
  }
  /* One buffer for the whole call: the middleware grows it to the largest message taken. */
  rcl_serialized_message_t message = {
    NULL, 0, 0, {allocate, deallocate, reallocate, zero_allocate, NULL}};
  rmw_message_info_t info;
  Py_ssize_t nbytes = 0;
  for (Py_ssize_t count = 0; count < max_count && nbytes < max_bytes; ++count) {
    memset(&info, 0, sizeof(info));
    int32_t ret = take(subscription, &message, &info, NULL);
    if (ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED) {
      break;
    }
    if (ret != RCL_RET_OK) {
      free(message.buffer);
      PyErr_Format(PyExc_RuntimeError, "rcl_take_serialized_message failed (rcl error %d)", ret);
      goto fail;
    }
    if (append_new(
        payloads,
        PyBytes_FromStringAndSize((const char *)message.buffer, (Py_ssize_t)message.buffer_length))
      || append_new(received, PyLong_FromLongLong(info.received_timestamp))
      || append_new(sources, PyLong_FromLongLong(info.source_timestamp))
      || append_new(sequences, PyLong_FromUnsignedLongLong(info.publication_sequence_number)))
    {
      free(message.buffer);
      goto fail;
    }
    nbytes += (Py_ssize_t)message.buffer_length;
  }
  free(message.buffer);
  return Py_BuildValue("(NNNNn)", payloads, received, sources, sequences, nbytes);

fail:
  Py_XDECREF(payloads);
  Py_XDECREF(received);
  Py_XDECREF(sources);
  Py_XDECREF(sequences);
  return NULL;
}

static PyMethodDef methods[] = {
  {"take_serialized", take_serialized, METH_VARARGS,
    "take_serialized(take, subscription, max_count, max_bytes) -> "
    "(payloads, received, sources, sequences, nbytes)"},
  {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
  PyModuleDef_HEAD_INIT, "_take", "Batched take of serialized messages from rcl.", -1, methods,
  NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__take(void)
{
  return PyModule_Create(&module);
}
